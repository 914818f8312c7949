"""Regenerate the shipped paper assets: the diagrams' data, the figures and the phase evidence.

Writes, from the current solver (no cache is read):

* ``rattle_core/assets/paper/fig2.npz``, ``fig4.npz``, ``fig5.npz``, ``fig6.npz`` (package
  data): the bifurcation sweeps
  of :data:`rattle_core.paper.cases.CASES`, compact (float32 impulses and phases) and keyed with
  their content key, so :func:`rattle_core.paper.cases.paper_sweep` serves them only while they
  match the solver;
* ``assets/paper/fig2.png`` … ``fig8.png``: the paper's figures, for the README;
* ``docs/phase_convention.md``: which reading of the paper's phases reproduces its claims.

Usage: ``python scripts/make_assets.py [--skip-evidence]``.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: The README's pictures of the paper's figures.
FIGURES_DIR = ROOT / "assets" / "paper"
sys.path.insert(0, str(ROOT))

from rattle_core.batch.sweep import sweep  # noqa: E402
from rattle_core.paper.cases import CASES, SWEEP_CASES  # noqa: E402
from rattle_core.paper.evidence import evidence_markdown, phase_convention_evidence  # noqa: E402
from rattle_core.paper.figures import write_paper_figures  # noqa: E402
from rattle_core.store.assets import ASSETS_DIR  # noqa: E402
from rattle_core.store.files import save_result  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skip-evidence", action="store_true",
                    help="do not recompute docs/phase_convention.md")
    args = ap.parse_args(argv)
    ASSETS_DIR.mkdir(parents=True, exist_ok=True)
    for key in SWEEP_CASES:
        case = CASES[key]
        t = time.perf_counter()
        res = sweep(case.params, case.name, case.values, **case.sweep_settings())
        path = ASSETS_DIR / f"{key}.npz"
        save_result(path, res, compact=True, key=case.cache_key())
        print(f"{path.relative_to(ROOT)}: {len(res.values)} values, {len(res.table)} impacts, "
              f"{path.stat().st_size / 1e6:.2f} MB, {time.perf_counter() - t:.1f} s")
    # A private cache: the figures must come from the assets just written or fresh runs,
    # never from an older cache entry.
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        paths = write_paper_figures(FIGURES_DIR, use_assets=True, evidence=False,
                                    cache_directory=tmp)
        for p in paths:
            print(f"{Path(p).relative_to(ROOT)}: {Path(p).stat().st_size / 1e3:.0f} kB")
        print(f"figures: {time.perf_counter() - t:.1f} s")
        if not args.skip_evidence:
            t = time.perf_counter()
            table = phase_convention_evidence(directory=tmp)
            doc = ROOT / "docs" / "phase_convention.md"
            doc.parent.mkdir(exist_ok=True)
            doc.write_text(evidence_markdown(table), encoding="utf-8")
            cols = ["reading"] + [f"claim{k}" for k in range(1, 6)] + ["all_hold"]
            print(table[cols].to_string(index=False))
            print(f"{doc.relative_to(ROOT)}: {time.perf_counter() - t:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
