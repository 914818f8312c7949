"""The disk cache's secret key: where it lives, how it is made, and the MAC entries carry.

A digest tells an accident from the content its writer meant; it cannot tell tampering,
since anyone who can write a file can recompute it.  Cache entries are therefore signed with
HMAC-SHA-256 under a key only the user holds (:func:`content_mac` in
:mod:`rattle_core.store.files`), over everything the entry says: the key of the request it
answers, and every array's name, type, shape and bytes (the stored request among them).

Key
    ``RATTLE_CACHE_KEY`` (hex, at least :data:`KEY_BYTES` bytes) when set, so several machines
    or containers can share one cache.  Otherwise the file :data:`KEY_FILE` in
    :func:`config_dir`, made on first use: :data:`KEY_BYTES` bytes from :mod:`secrets`, written
    as hex to a temporary file of mode 0600 and linked into place, so two processes starting
    at once agree on one key and no reader ever sees half of one.
A bad key is an error, not a new key
    A key file that is not a regular file, is readable or writable by others, or does not hold
    a key, and a malformed ``RATTLE_CACHE_KEY``, raise :class:`CacheKeyError` (a
    ``ValueError``) naming the file or variable and what to do: replacing a key silently would
    hide that someone changed it.  Deleting the file makes a new key at the next use (every
    entry is then recomputed once).
No key at all
    When the config directory cannot be written, :func:`secret` raises ``OSError``; the cache
    then neither serves nor stores anything (an entry it cannot verify is never served) and the
    result is computed, as with a read-only cache directory.
"""
from __future__ import annotations

import os
import secrets
import stat
import tempfile
from pathlib import Path

#: Bytes of a key (HMAC-SHA-256 takes a key of the hash's size).
KEY_BYTES = 32
#: The key's file name in :func:`config_dir`.
KEY_FILE = "cache.key"
#: The environment variable that gives the key as hex instead of the file.
KEY_ENV = "RATTLE_CACHE_KEY"


class CacheKeyError(ValueError):
    """The cache key (its file or ``RATTLE_CACHE_KEY``) is unusable; the message says why."""


def config_dir() -> Path:
    """``$RATTLE_CONFIG_DIR``, else ``$XDG_CONFIG_HOME/rattle-explorer``, else
    ``~/.config/rattle-explorer``."""
    env = os.environ.get("RATTLE_CONFIG_DIR")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CONFIG_HOME")
    return (Path(xdg) if xdg else Path.home() / ".config") / "rattle-explorer"


def key_path() -> Path:
    """Where the cache key is kept (unless ``RATTLE_CACHE_KEY`` is set)."""
    return config_dir() / KEY_FILE


def _parse(text: str, where: str, remedy: str = "") -> bytes:
    try:
        key = bytes.fromhex(text.strip())
    except ValueError:
        key = b""
    if len(key) < KEY_BYTES:
        # the text itself is not shown: it may be most of a secret
        raise CacheKeyError(f"{where} must hold at least {2 * KEY_BYTES} hex digits "
                            f"({KEY_BYTES} bytes); it holds {len(text.strip())} characters that "
                            f"are not such a key{remedy}")
    return key


def secret() -> bytes:
    """The cache key: from ``RATTLE_CACHE_KEY``, else read (or made, on first use) from
    :func:`key_path`.  Raises :class:`CacheKeyError` for a bad key, ``OSError`` when none can
    be made."""
    env = os.environ.get(KEY_ENV)
    if env is not None and env.strip():
        return _parse(env, KEY_ENV)
    path = key_path()
    try:
        return _read(path)
    except (FileNotFoundError, NotADirectoryError):
        _create(path)  # raises OSError when the directory cannot be made: no key, no cache
    except OSError as exc:  # there, but not ours to read (permissions, a symlink)
        raise CacheKeyError(f"cache key {str(path)!r} cannot be read ({exc.strerror or exc}); "
                            f"fix its permissions (chmod 600), or delete it to make a new "
                            f"key") from None
    return _read(path)


def _read(path: Path) -> bytes:
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise CacheKeyError(f"cache key {str(path)!r} is not a regular file; delete it, and "
                                f"a new key is made at the next use")
        if st.st_mode & 0o077:
            raise CacheKeyError(f"cache key {str(path)!r} has mode {stat.S_IMODE(st.st_mode):04o}"
                                f": others may read or change it; run chmod 600 on it, or "
                                f"delete it to make a new key")
        data = os.read(fd, 4096)
    finally:
        os.close(fd)
    try:
        text = data.decode("ascii")
    except UnicodeDecodeError:
        text = "?" * len(data)
    return _parse(text, f"cache key {str(path)!r}", "; delete it to make a new key")


def _create(path: Path) -> None:
    """Write a new key to ``path`` unless another process got there first."""
    path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-key-")  # mode 0600
    try:
        with os.fdopen(fd, "w") as f:
            f.write(secrets.token_hex(KEY_BYTES) + "\n")
            f.flush()
            os.fsync(f.fileno())
        try:
            os.link(tmp, path)  # fails if a key exists: the first writer's key stays
        except FileExistsError:
            pass
        except OSError:  # a file system without hard links: exclusive creation instead
            try:
                out = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
            except FileExistsError:
                return
            with os.fdopen(out, "w") as f:
                f.write(Path(tmp).read_text())
    finally:
        os.unlink(tmp)
