"""How loud a rattle is: loudness (ISO 532-1, Zwicker, time-varying) and sharpness (DIN 45692).

Every stage is compiled (``numba``, ``nogil``), so sounds measured from several threads run on
all cores at once:

1. the third-octave filter bank: 28 bands, each three second-order sections with ISO 532-1's
   coefficients (Annex A), squared, smoothed by three first-order low-passes and sampled every
   0.5 ms as a level in dB;
2. the core loudness of 20 critical bands (ISO 532-1, clause 6.4: the low bands' correction,
   the threshold in quiet, the transmission of the outer ear);
3. the nonlinear temporal decay of hearing (clause 6.5), on 24 interpolated steps per 0.5 ms;
4. the slopes: the specific loudness over 240 steps of 0.1 Bark and its integral, the total
   loudness (clause 6.6);
5. the temporal weighting of the total loudness: two first-order low-passes (3.5 and 70 ms) on
   24 interpolated steps.

DIN 45692 sharpness is the specific loudness weighted by ``g(z)`` and integrated (compiled too).
The numbers are those of MOSQITO 1.2.1's ``loudness_zwtv`` and ``sharpness_din_from_loudness``
(``mosqito.sq_metrics``) including the way it resolves ISO 532-1's slope loop and its
rounding of comparisons to 8 decimals: the test suite checks ``N(t)``, ``N5``, the specific
loudness and the sharpness against MOSQITO itself to 1e-9 relative.

Single numbers
    ``loudness_sone`` is ``N5``, the loudness exceeded 5 % of the time (ISO 532-1's figure for
    time-varying sounds); ``sharpness_acum`` is the mean DIN 45692 sharpness over the frames
    with loudness.  The first :data:`SKIP_S` seconds are left out of both (the filters settle).
    A silent signal is 0 sone and 0 acum.
Incoherent sources
    Sounds from independent sources (a gearbox's gears, each heard through its own path) have
    unrelated phases: their energies add, not their pressures.  Adding the pressures of two
    rattle sounds lets their ringing cancel in places, so the total could be quieter than one
    of its parts.  :func:`loudness_incoherent` adds the sources' third-octave band intensities
    (stage 1's output, sample by sample) and runs stages 2 to 5 on the sum.  Every later stage
    grows with the band levels, so the total is never quieter than its loudest part; and of one
    source it is that source's loudness, exactly.
From impulses to sound pressure
    Loudness is not linear in level, so the sound needs an absolute level.  The rattle sound of
    :mod:`rattle_core.analysis.sound` rings the housing's modes with each impact's impulse in
    N·s; the sound pressure at the listener is that signal times a transfer ``T`` [Pa per N·s]:
    the peak pressure that a 1 N·s tooth impulse makes through a mode of gain 1.  The default
    :data:`~rattle_core.model.gearbox.DEFAULT_TRANSFER_PA_PER_NS` = 5 Pa/(N·s) puts a small
    car gearbox's rattle (impulses of 1 to 20 mN·s, some hundred a second) at 70 to 85 dB near
    the housing, 10 to 40 sone.  It is illustrative, not
    measured: give your own from a measured impulse response or a calibrated impact.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
from numba import njit

from ..model.gearbox import DEFAULT_TRANSFER_PA_PER_NS

#: Sample rate ISO 532-1 asks for [Hz].
SAMPLE_RATE = 48_000
#: Settling time left out of the single numbers [s].
SKIP_S = 0.05
#: Field type of ISO 532-1 used throughout.
FIELD = "free"
#: Highest third-octave level below 315 Hz that the method covers [dB].
MAX_LOW_LEVEL_DB = 120.0

# ----- ISO 532-1 tables -------------------------------------------------------------------------

#: Samples of the 48 kHz signal per level sample (levels every 0.5 ms, 2 kHz).
_DECIMATE = SAMPLE_RATE // 2000
#: Interpolated steps per level sample of the nonlinear decay and of the temporal weighting.
_STEPS = 24
#: Level samples per output sample: ``N(t)`` every 2 ms.
_OUT_EVERY = 4

# Annex A, Table A.2: each band's three sections as differences (a1, a2) to the reference
# sections of Table A.1 (b = [1, 2, 1], [1, 0, −1], [1, −2, 1]; a = [1, −2, 1]).
_SECTION_DIFF = np.array([
    [[-6.70260e-4, 6.59453e-4], [-3.75071e-4, 3.61926e-4], [-3.06523e-4, 2.97634e-4]],
    [[-8.47258e-4, 8.30131e-4], [-4.76448e-4, 4.55616e-4], [-3.88773e-4, 3.74685e-4]],
    [[-1.07210e-3, 1.04496e-3], [-6.06567e-4, 5.73553e-4], [-4.94004e-4, 4.71677e-4]],
    [[-1.35836e-3, 1.31535e-3], [-7.74327e-4, 7.22007e-4], [-6.29154e-4, 5.93771e-4]],
    [[-1.72380e-3, 1.65564e-3], [-9.91780e-4, 9.08866e-4], [-8.03529e-4, 7.47455e-4]],
    [[-2.19188e-3, 2.08388e-3], [-1.27545e-3, 1.14406e-3], [-1.02976e-3, 9.40900e-4]],
    [[-2.79386e-3, 2.62274e-3], [-1.64828e-3, 1.44006e-3], [-1.32520e-3, 1.18438e-3]],
    [[-3.57182e-3, 3.30071e-3], [-2.14252e-3, 1.81258e-3], [-1.71397e-3, 1.49082e-3]],
    [[-4.58305e-3, 4.15355e-3], [-2.80413e-3, 2.28135e-3], [-2.23006e-3, 1.87646e-3]],
    [[-5.90655e-3, 5.22622e-3], [-3.69947e-3, 2.87118e-3], [-2.92205e-3, 2.36178e-3]],
    [[-7.65243e-3, 6.57493e-3], [-4.92540e-3, 3.61318e-3], [-3.86007e-3, 2.97240e-3]],
    [[-1.00023e-2, 8.29610e-3], [-6.63788e-3, 4.55999e-3], [-5.15982e-3, 3.75306e-3]],
    [[-1.31230e-2, 1.04220e-2], [-9.02274e-3, 5.73132e-3], [-6.94543e-3, 4.71734e-3]],
    [[-1.73693e-2, 1.30947e-2], [-1.24176e-2, 7.20526e-3], [-9.46002e-3, 5.93145e-3]],
    [[-2.31934e-2, 1.64308e-2], [-1.73009e-2, 9.04761e-3], [-1.30358e-2, 7.44926e-3]],
    [[-3.13292e-2, 2.06370e-2], [-2.44342e-2, 1.13731e-2], [-1.82108e-2, 9.36778e-3]],
    [[-4.28261e-2, 2.59325e-2], [-3.49619e-2, 1.43046e-2], [-2.57855e-2, 1.17912e-2]],
    [[-5.91733e-2, 3.25054e-2], [-5.06072e-2, 1.79513e-2], [-3.69401e-2, 1.48094e-2]],
    [[-8.26348e-2, 4.05894e-2], [-7.40348e-2, 2.24476e-2], [-5.34977e-2, 1.85371e-2]],
    [[-1.17018e-1, 5.08116e-2], [-1.09516e-1, 2.81387e-2], [-7.85097e-2, 2.32872e-2]],
    [[-1.67714e-1, 6.37872e-2], [-1.63378e-1, 3.53729e-2], [-1.16419e-1, 2.93723e-2]],
    [[-2.42528e-1, 7.98576e-2], [-2.45161e-1, 4.43370e-2], [-1.73972e-1, 3.70015e-2]],
    [[-3.53142e-1, 9.96330e-2], [-3.69163e-1, 5.53535e-2], [-2.61399e-1, 4.65428e-2]],
    [[-5.16316e-1, 1.24177e-1], [-5.55473e-1, 6.89403e-2], [-3.93998e-1, 5.86715e-2]],
    [[-7.56635e-1, 1.55023e-1], [-8.34281e-1, 8.58123e-2], [-5.94547e-1, 7.43960e-2]],
    [[-1.10165e0, 1.91713e-1], [-1.23939e0, 1.05243e-1], [-8.91666e-1, 9.40354e-2]],
    [[-1.58477e0, 2.39049e-1], [-1.80505e0, 1.28794e-1], [-1.32500e0, 1.21333e-1]],
    [[-2.50630e0, 1.42308e-1], [-2.19464e0, 2.76470e-1], [-1.90231e0, 1.47304e-1]],
])
# Table A.2: each band's gain.
_BAND_GAIN = np.array([
    4.30764e-11, 8.59340e-11, 1.71424e-10, 3.41944e-10, 6.82035e-10, 1.36026e-09, 2.71261e-09,
    5.40870e-09, 1.07826e-08, 2.14910e-08, 4.28228e-08, 8.54316e-08, 1.70009e-07, 3.38215e-07,
    6.71990e-07, 1.33531e-06, 2.65172e-06, 5.25477e-06, 1.03780e-05, 2.04870e-05, 4.05198e-05,
    7.97914e-05, 1.56511e-04, 3.04954e-04, 5.99157e-04, 1.16544e-03, 2.27488e-03, 3.91006e-03])
_BANDS = _BAND_GAIN.size


def _sections() -> np.ndarray:
    """Per band and section, ``[b0, b1, b2, a1, a2]`` (``a0 = 1``): reference minus difference."""
    ref = np.array([[1, 2, 1, 1, -2, 1], [1, 0, -1, 1, -2, 1], [1, -2, 1, 1, -2, 1]])
    diff = np.zeros((_BANDS, 3, 6))
    diff[:, :, 4:] = _SECTION_DIFF
    full = ref - diff
    return np.ascontiguousarray(full[:, :, [0, 1, 2, 4, 5]])


def _smoothing() -> np.ndarray:
    """Per band, the pole of its three smoothing low-passes: time constant ``2 / (3 f_c)``,
    at most 2/3 ms (clause 6.3)."""
    pole = np.empty(_BANDS)
    for b in range(_BANDS):
        centre = 10 ** ((b - 16) / 10) * 1000
        tau = 2 / (3 * centre) if centre <= 1000 else 2 / (3 * 1000)
        pole[b] = math.exp(-1 / (SAMPLE_RATE * tau))
    return pole


def _bank_coefficients() -> np.ndarray:
    """The filter bank's numbers as one flat array, band fastest: rows 0–14 the three sections'
    ``b0, b1, b2, a1, a2``, row 15 the gain, rows 16 and 17 the smoothing ``p`` and ``1 − p``."""
    sos, pole = _sections(), _smoothing()
    coef = np.empty((18, _BANDS))
    for s in range(3):
        for k in range(5):
            coef[5 * s + k] = sos[:, s, k]
    coef[15] = _BAND_GAIN
    coef[16] = pole
    coef[17] = 1 - pole
    return coef.ravel()


_BANK = _bank_coefficients()
#: Intensity floor and reference of the band levels (``10 log10((I + floor) / ref)``).
_FLOOR = 10 ** -12
_I_REF = 4 * 10 ** -10

# Table 3 (clause 6.4): the low bands' level ranges and corrections.
_RAP = np.array([45, 55, 65, 71, 80, 90, 100, 120], dtype=np.float64)
_DLL = np.array([
    [-32, -24, -16, -10, -5, 0, -7, -3, 0, -2, 0],
    [-29, -22, -15, -10, -4, 0, -7, -2, 0, -2, 0],
    [-27, -19, -14, -9, -4, 0, -6, -2, 0, -2, 0],
    [-25, -17, -12, -9, -3, 0, -5, -2, 0, -2, 0],
    [-23, -16, -11, -7, -3, 0, -4, -1, 0, -1, 0],
    [-20, -14, -10, -6, -3, 0, -4, -1, 0, -1, 0],
    [-18, -12, -9, -6, -2, 0, -3, -1, 0, -1, 0],
    [-15, -10, -8, -4, -2, 0, -3, -1, 0, -1, 0]], dtype=np.float64)
# Tables 4–6: threshold in quiet, free-field transmission, critical-band level correction.
_LTQ = np.array([30, 18, 12, 8, 7, 6, 5, 4, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3], dtype=np.float64)
_A0 = np.array([0, 0, 0, 0, 0, 0, 0, 0, 0, 0, -0.5, -1.6, -3.2, -5.4, -5.6, -4, -1.5, 2, 5, 12],
               dtype=np.float64)
_DCB = np.array([-0.25, -0.6, -0.8, -0.8, -0.5, 0, 0.5, 1.1, 1.5, 1.7, 1.8, 1.8, 1.7, 1.6, 1.4,
                 1.2, 0.8, 0.5, 0, -0.5])
_MP1 = 0.0635 * np.power(10, 0.025 * _LTQ)
#: Core loudness rows: 20 critical bands and a 21st of zeros.
_BANDS_CORE = _LTQ.size + 1

# Tables 7 and 8 (clause 6.6): upper limits of the critical bands [Bark], the loudness steps
# of the slopes' table and the slopes themselves (18 steps × 8 band groups, the last group
# continuing to 21 bands).
_ZUP = np.array([0.9, 1.8, 2.8, 3.5, 4.4, 5.4, 6.6, 7.9, 9.2, 10.6, 12.3, 13.8, 15.2, 16.7,
                 18.1, 19.3, 20.6, 21.8, 22.7, 23.6, 24])
_RNS = np.array([21.5, 18, 15.1, 11.5, 9, 6.1, 4.4, 3.1, 2.13, 1.36, 0.82, 0.42, 0.30, 0.22,
                 0.15, 0.10, 0.035, 0])
_USL8 = np.array([
    [13, 8.2, 6.3, 5.5, 5.5, 5.5, 5.5, 5.5],
    [9, 7.5, 6, 5.1, 4.5, 4.5, 4.5, 4.5],
    [7.8, 6.7, 5.6, 4.9, 4.4, 3.9, 3.9, 3.9],
    [6.2, 5.4, 4.6, 4.0, 3.5, 3.2, 3.2, 3.2],
    [4.5, 3.8, 3.6, 3.2, 2.9, 2.7, 2.7, 2.7],
    [3.7, 3.0, 2.8, 2.35, 2.2, 2.2, 2.2, 2.2],
    [2.9, 2.3, 2.1, 1.9, 1.8, 1.7, 1.7, 1.7],
    [2.4, 1.7, 1.5, 1.35, 1.3, 1.3, 1.3, 1.3],
    [1.95, 1.45, 1.3, 1.15, 1.1, 1.1, 1.1, 1.1],
    [1.5, 1.2, 0.94, 0.86, 0.82, 0.82, 0.82, 0.82],
    [0.72, 0.67, 0.64, 0.63, 0.62, 0.62, 0.62, 0.62],
    [0.59, 0.53, 0.51, 0.50, 0.42, 0.42, 0.42, 0.42],
    [0.40, 0.33, 0.26, 0.24, 0.24, 0.22, 0.22, 0.22],
    [0.27, 0.21, 0.20, 0.18, 0.17, 0.17, 0.17, 0.17],
    [0.16, 0.15, 0.14, 0.12, 0.11, 0.11, 0.11, 0.11],
    [0.12, 0.11, 0.10, 0.08, 0.08, 0.08, 0.08, 0.08],
    [0.09, 0.08, 0.07, 0.06, 0.06, 0.06, 0.06, 0.05],
    [0.06, 0.05, 0.03, 0.02, 0.02, 0.02, 0.02, 0.02]])
_USL = np.ascontiguousarray(np.hstack([_USL8, np.repeat(_USL8[:, 7:], _ZUP.size - 8, axis=1)]))
#: Last 0.1-Bark step (exclusive) of each critical band; the Bark values are not all exact in
#: binary, so the steps are the truncated products, as the reference computes them.
_ZUP_STEP = (_ZUP * 10).astype(np.int32).astype(np.int64)
#: Number of 0.1-Bark steps of the specific loudness.
_SPEC = 240
#: Loudness comparisons of the slopes are made on values rounded to this many decimals.
_DECIMALS = 8
_RNS_SCALED = np.rint(_RNS * 10.0 ** _DECIMALS)

# DIN 45692: the weighting g(z) of sharpness, times z·Δz, on the Bark axis of N'.
BARK = np.linspace(0.1, 24, int(24 / 0.1))
_G_DIN = np.ones(BARK.size)
_G_DIN[BARK > 15.8] = 0.15 * np.exp(0.42 * (BARK[BARK > 15.8] - 15.8)) + 0.85


def _decay_constants() -> np.ndarray:
    """The nonlinear decay's six coefficients (clause 6.5: time constants 5, 15 and 75 ms)."""
    t_short, t_long, t_var = 0.005, 0.015, 0.075
    dt = 1 / (2000 * _STEPS)
    P = (t_var + t_long) / (t_var * t_short)
    Q = 1 / (t_short * t_var)
    l1 = -P / 2 + math.sqrt(P * P / 4 - Q)
    l2 = -P / 2 - math.sqrt(P * P / 4 - Q)
    den = t_var * (l1 - l2)
    e1, e2 = math.exp(l1 * dt), math.exp(l2 * dt)
    return np.array([(e1 - e2) / den,
                     ((t_var * l2 + 1) * e1 - (t_var * l1 + 1) * e2) / den,
                     ((t_var * l1 + 1) * e1 - (t_var * l2 + 1) * e2) / den,
                     (t_var * l1 + 1) * (t_var * l2 + 1) * (e1 - e2) / den,
                     math.exp(-dt / t_long),
                     math.exp(-dt / t_var)])


_DECAY = _decay_constants()
# Clause 6.7: the temporal weighting's two low-passes (3.5 ms, 70 ms) and their weights.
_WEIGHT_POLES = np.array([math.exp(-1 / (2000 * _STEPS * tau))
                          for tau in (3.5 * 10 ** -3, 70 * 10 ** -3)])
_WEIGHTS = (0.47, 0.53)


# ----- the compiled stages ----------------------------------------------------------------------

@njit(cache=True, nogil=True)
def _band_levels(x, coef, floor, i_ref, every):
    """Stage 1: each band's level [dB] every ``every`` samples, shape ``(bands, ceil(n/every))``.

    Per sample, every band runs its three sections (direct form II transposed), its gain, the
    square and its three smoothing low-passes ``y ← p y + (1 − p) u``.  ``coef`` is
    :func:`_bank_coefficients`: one flat array, band fastest, and the state is one flat array
    too, so the bands (independent of each other) form the inner loop and the compiler
    vectorises across them."""
    NB = _BANDS
    n = x.size
    m = (n + every - 1) // every
    out = np.empty((NB, m))
    st = np.zeros(9 * NB)
    for t in range(n):
        xt = x[t]
        for b in range(NB):
            y = coef[b] * xt + st[b]
            st[b] = coef[NB + b] * xt - coef[3 * NB + b] * y + st[NB + b]
            st[NB + b] = coef[2 * NB + b] * xt - coef[4 * NB + b] * y
            u = y
            y = coef[5 * NB + b] * u + st[2 * NB + b]
            st[2 * NB + b] = coef[6 * NB + b] * u - coef[8 * NB + b] * y + st[3 * NB + b]
            st[3 * NB + b] = coef[7 * NB + b] * u - coef[9 * NB + b] * y
            u = y
            y = coef[10 * NB + b] * u + st[4 * NB + b]
            st[4 * NB + b] = coef[11 * NB + b] * u - coef[13 * NB + b] * y + st[5 * NB + b]
            st[5 * NB + b] = coef[12 * NB + b] * u - coef[14 * NB + b] * y
            y = coef[15 * NB + b] * y
            y = y * y
            p = coef[16 * NB + b]
            q = coef[17 * NB + b]
            a = p * st[6 * NB + b] + q * y
            st[6 * NB + b] = a
            a = p * st[7 * NB + b] + q * a
            st[7 * NB + b] = a
            st[8 * NB + b] = p * st[8 * NB + b] + q * a
        if t % every == 0:
            c = t // every
            for b in range(NB):
                out[b, c] = 10 * math.log10((st[8 * NB + b] + floor) / i_ref)
    return out


@njit(cache=True, nogil=True)
def _core_loudness(levels, rap, dll, ltq, a0, dcb, mp1):
    """Stage 2: core loudness of the 20 critical bands and a 21st of zeros, per level sample."""
    m = levels.shape[1]
    nb = ltq.size
    out = np.zeros((nb + 1, m))
    ti = np.empty(11)
    le = np.empty(nb)
    for c in range(m):
        # bands up to 250 Hz: a level-dependent correction, then three critical bands
        for b in range(11):
            lv = levels[b, c]
            prev = lv > rap[0] - dll[0, b]
            d = 0.0 if prev else dll[0, b]
            for k in range(1, rap.size - 1):
                cur = lv > rap[k] - dll[k, b]
                if cur != prev:
                    d = dll[k, b]
                prev = cur
            ti[b] = 10.0 ** ((d + lv) / 10)
        g0 = ti[0] + ti[1] + ti[2] + ti[3] + ti[4] + ti[5]
        g1 = ti[6] + ti[7] + ti[8]
        g2 = ti[9] + ti[10]
        le[0] = 10 * math.log10(g0) if g0 > 0 else 0.0
        le[1] = 10 * math.log10(g1) if g1 > 0 else 0.0
        le[2] = 10 * math.log10(g2) if g2 > 0 else 0.0
        for k in range(3, nb):
            le[k] = levels[8 + k, c]
        for k in range(nb):
            v = le[k] - a0[k]
            if v > ltq[k]:
                v = v - dcb[k]
                n = mp1[k] * ((0.75 + 0.25 * 10.0 ** (0.1 * (v - ltq[k]))) ** 0.25 - 1)
                out[k, c] = n if n > 0 else 0.0
        korr = 0.4 + 0.32 * out[0, c] ** 0.2
        if korr <= 1:
            out[0, c] *= korr
    return out


@njit(cache=True, nogil=True)
def _nonlinear_decay(core, B, steps):
    """Stage 3: the decay of each band, run on ``steps`` linear steps between level samples.

    The state before the first step is the last step's input (the signal read as periodic) and a
    zero second state.  The bands are the inner loop (the state in one flat array, the choices
    as selects), so the compiler vectorises across them."""
    R = _BANDS_CORE
    m = core.shape[1]
    out = np.empty((m, R))
    w = np.zeros(4 * R)  # per band: the input x, its step, the states uo and u2
    for i in range(R):
        last = core[i, m - 1]
        d_last = (0.0 - last) / steps
        for k in range(1, steps):
            last = last + d_last
        w[2 * R + i] = last
    for c in range(m):
        for i in range(R):
            nxt = core[i, c + 1] if c + 1 < m else 0.0
            w[R + i] = (nxt - core[i, c]) / steps
            w[i] = core[i, c]
        for k in range(steps):
            for i in range(R):
                x = w[i]
                if k > 0:
                    x = x + w[R + i]
                uo_p = w[2 * R + i]
                u2_p = w[3 * R + i]
                falling = uo_p > u2_p
                rising = uo_p <= u2_p
                v = uo_p * B[2] - u2_p * B[3]
                uo = v if (falling & (v >= x)) else x
                v = uo_p * B[4]
                uo = v if (rising & (v >= x)) else uo
                v = uo_p * B[0] - u2_p * B[1]
                u2 = v if ((x < uo_p) & falling & (v <= uo)) else uo
                near = (abs(x - uo_p) < 1e-5) & (uo <= u2_p)
                v = (u2_p - x) * B[5] + x
                u2 = v if ((x >= uo_p) & (not near)) else u2
                w[i] = x
                w[2 * R + i] = uo
                w[3 * R + i] = u2
            if k == 0:
                for i in range(R):
                    out[c, i] = w[2 * R + i]
    return out.T.copy()


@njit(cache=True, nogil=True)
def _scaled(v):
    """``v`` rounded to :data:`_DECIMALS` decimals, times ``10**_DECIMALS``: comparing these
    compares the rounded values (the division back is monotone for loudness values)."""
    return np.rint(v * 1e8)


@njit(cache=True, nogil=True)
def _step_index(v, rns_scaled, equal):
    """The row of the slopes' table for loudness ``v``: how many steps lie above it (at most 17)."""
    r = _scaled(v)
    count = 0
    if equal:
        for k in range(rns_scaled.size):
            count += r <= rns_scaled[k]
    else:
        for k in range(rns_scaled.size):
            count += r < rns_scaled[k]
    return min(count, rns_scaled.size - 1)


@njit(cache=True, nogil=True)
def _slopes(nl, zup, rns, rns_scaled, usl, zstep, spec_len, every):
    """Stage 4: total loudness per level sample, and the specific loudness every ``every``.

    Each sample walks up the critical bands; where a band is quieter than the one below, the
    upper slope of the louder band falls over the next 0.1-Bark steps (Table 8's slopes), and
    the loudness is the area under the resulting curve, rounded as ISO 532-1's program rounds
    it (to 0.001 sone up to 16 sone, to 0.01 sone above).  Loudness and Bark values are
    compared rounded to 8 decimals."""
    nb, m = nl.shape
    total = np.empty(m)
    spec_out = np.zeros((spec_len, (m + every - 1) // every))
    n2 = np.empty(spec_len)   # the curve's loudness at each step's upper edge
    z2 = np.empty(spec_len)   # and its Bark value
    us = np.empty(spec_len)   # the slope in force there
    rv = np.empty(spec_len)   # the table's loudness step in force there
    sp = np.empty(spec_len)   # specific loudness
    for c in range(m):
        keep = c % every == 0
        # Each band starts flat at its core loudness.  Within a band, the walk below writes a
        # step before it reads it, so only a band's first and last steps need their values
        # (and the specific loudness only in the frames that are kept).
        for i in range(nb):
            lo = zstep[i - 1] if i > 0 else 0
            hi = zstep[i] - 1
            v = nl[i, c]
            n2[lo] = v
            n2[hi] = v
            z2[lo] = zup[i]
            z2[hi] = zup[i]
            rv[hi] = rns[_step_index(v, rns_scaled, False)]
            if keep:
                vs = v if i < nb - 1 else 0.0
                for r in range(lo, hi + 1):
                    sp[r] = vs
        N = 0.0
        n1 = 0.0
        z1 = 0.0
        for i in range(nb):
            # band 0 reads "the band below" from the top of the table, as the reference does
            im1 = i - 1 if i > 0 else nb - 1
            first = zstep[i - 1] if i > 0 else 0
            below = first - 1 if first > 0 else spec_len - 1
            nm = nl[i, c]
            nm_s = _scaled(nm)
            idx = _step_index(n2[below], rns_scaled, False)
            rv[first] = rns[idx]
            us[first] = usl[idx, im1]
            if not _scaled(n2[below]) > nm_s:
                N += n2[first] * (z2[first] - z1)
                n1 = n2[first]
                z1 = z2[first]
                continue
            # the band is quieter: the slope of the band below falls into it
            mx = max(rv[below], nm)
            z2[first] = min((n1 - mx) / us[first] + z1, zup[i])
            dz = z2[first] - z1
            n2[first] = n1 - dz * us[first]
            N += dz * (n1 + n2[first]) / 2
            z = zup[im1] + 0.1
            last = first
            last_hit = False
            for j in range(first, zstep[i]):
                if j != first:
                    z2[j] = z2[j - 1]
                    n2[j] = n2[j - 1]
                    us[j] = us[j - 1]
                    rv[j] = rv[j - 1]
                hit = _scaled(z2[j]) <= _scaled(z)
                done = False
                if hit:
                    idx = _step_index(n2[j], rns_scaled, True)
                    rv[j] = rns[idx]
                    us[j] = usl[idx, im1]
                    n1 = n2[j]
                    z1 = z2[j]
                    if _scaled(n1) <= nm_s:
                        n2[j] = nm
                        z2[j] = zup[i]
                        N += n2[j] * (z2[j] - z1)
                        done = True
                    else:
                        mx = max(rv[j], nm)
                        z2[j] = min((n1 - mx) / us[j] + z1, zup[i])
                        dz = z2[j] - z1
                        n2[j] = n1 - dz * us[j]
                        N += dz * (n1 + n2[j]) / 2
                        if keep:
                            sp[j] = n1 - (z - z1) * us[j]
                elif keep:
                    sp[j] = n1 - (z - z1) * us[j]
                z += 0.1
                z1 = z2[j]
                n1 = n2[j]
                last = j
                last_hit = hit
                if done:
                    break
            z1 = z2[zstep[i] - 1]
            n1 = n2[zstep[i] - 1]
            if last_hit:
                idx = _step_index(n2[last], rns_scaled, True)
                rv[last] = rns[idx]
                us[last] = usl[idx, im1]
        if N < 0:
            N = 0.0
        if N <= 16:
            N = math.floor(N * 1000 + 0.5) / 1000
        else:
            N = math.floor(N * 100 + 0.5) / 100
        total[c] = N
        if keep:
            for r in range(spec_len):
                spec_out[r, c // every] = sp[r]
    return total, spec_out


@njit(cache=True, nogil=True)
def _lowpass_steps(x, pole, steps):
    """A first-order low-pass run on ``steps`` linear steps between samples; its value at each
    sample (the step after the last sample falls towards zero)."""
    m = x.size
    out = np.empty(m)
    q = 1 - pole
    y = 0.0
    for c in range(m):
        nxt = x[c + 1] if c + 1 < m else 0.0
        d = (nxt - x[c]) / steps
        u = x[c]
        for k in range(steps):
            if k > 0:
                u = u + d
            y = pole * y + q * u
            if k == 0:
                out[c] = y
    return out


@njit(cache=True, nogil=True)
def _temporal_weighting(total, poles, w0, w1, steps):
    """Stage 5: ``0.47 LP(3.5 ms) + 0.53 LP(70 ms)`` of the total loudness."""
    f0 = _lowpass_steps(total, poles[0], steps)
    f1 = _lowpass_steps(total, poles[1], steps)
    return w0 * f0 + w1 * f1


@njit(cache=True, nogil=True)
def _sharpness(N, spec, g, z):
    """DIN 45692 sharpness ``S = 0.11 Σ N'(z) g(z) z Δz / N`` per frame; 0 where N < 0.1 sone."""
    rows, m = spec.shape
    S = np.zeros(m)
    for c in range(m):
        if N[c] < 0.1:
            continue
        acc = 0.0
        for r in range(rows):
            acc += spec[r, c] * g[r] * z[r] * 0.1
        S[c] = 0.11 * acc / N[c]
    return S


@njit(cache=True, nogil=True)
def _zwtv_levels(levels, rap, dll, ltq, a0, dcb, mp1, B, zup, rns, rns_scaled, usl, zstep,
                 poles, w0, w1):
    """Stages 2 to 5 from the third-octave levels of stage 1."""
    low = -np.inf
    for b in range(11):
        for c in range(levels.shape[1]):
            low = max(low, levels[b, c])
    core = _core_loudness(levels, rap, dll, ltq, a0, dcb, mp1)
    nl = _nonlinear_decay(core, B, _STEPS)
    total, spec = _slopes(nl, zup, rns, rns_scaled, usl, zstep, _SPEC, _OUT_EVERY)
    weighted = _temporal_weighting(total, poles, w0, w1, _STEPS)
    return weighted[::_OUT_EVERY].copy(), spec, low


@njit(cache=True, nogil=True)
def _zwtv(x, coef, floor, i_ref, rap, dll, ltq, a0, dcb, mp1, B, zup, rns,
          rns_scaled, usl, zstep, poles, w0, w1):
    """All five stages: ``N(t)`` and ``N'(z, t)`` every 2 ms, and the highest level of the
    bands below 315 Hz (the method holds up to 120 dB)."""
    levels = _band_levels(x, coef, floor, i_ref, _DECIMATE)
    return _zwtv_levels(levels, rap, dll, ltq, a0, dcb, mp1, B, zup, rns, rns_scaled, usl,
                        zstep, poles, w0, w1)


def _check_signal(signal, fs) -> np.ndarray:
    if fs != SAMPLE_RATE:
        raise ValueError(f"fs = {fs!r} is not allowed; ISO 532-1 loudness here takes "
                         f"{SAMPLE_RATE} Hz")
    x = np.ascontiguousarray(signal, dtype=np.float64)
    if x.ndim != 1 or x.size < 1:
        raise ValueError(f"signal must be a one-dimensional sound pressure [Pa], got shape "
                         f"{x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("signal must be finite")
    return x


def loudness_zwtv(signal: np.ndarray, fs: int = SAMPLE_RATE):
    """ISO 532-1 time-varying loudness (free field), as ``mosqito.sq_metrics.loudness_zwtv``.

    Parameters
    ----------
    signal : ndarray
        Sound pressure [Pa] at ``fs``.
    fs : int
        48 000 Hz.

    Returns
    -------
    N : ndarray
        Total loudness ``N(t)`` [sone], every 2 ms.
    N_specific : ndarray
        Specific loudness ``N'(z, t)`` [sone/Bark], shape ``(240, len(N))``.
    bark_axis : ndarray
        ``z`` = 0.1 to 24 Bark.
    time_axis : ndarray
        ``t`` [s] of each frame.

    Raises
    ------
    ValueError
        ``fs`` other than 48 kHz, a signal that is not one-dimensional and finite, or a
        third-octave level below 315 Hz over 120 dB (outside the method's range).
    """
    x = _check_signal(signal, fs)
    N, spec, low = _zwtv(x, _BANK, _FLOOR, _I_REF, _RAP, _DLL, _LTQ, _A0,
                         _DCB, _MP1, _DECAY, _ZUP, _RNS, _RNS_SCALED, _USL, _ZUP_STEP,
                         _WEIGHT_POLES, *_WEIGHTS)
    if low > MAX_LOW_LEVEL_DB:
        raise ValueError(f"signal has a third-octave level of {low:.1f} dB below 315 Hz; the "
                         f"allowed range is up to {MAX_LOW_LEVEL_DB:g} dB (ISO 532-1's range)")
    frames = (x.size + _DECIMATE - 1) // _DECIMATE
    time_axis = np.linspace(0, x.size / fs, num=frames)[::_OUT_EVERY]
    return N, spec, BARK.copy(), time_axis


def sharpness_din(N: np.ndarray, N_specific: np.ndarray) -> np.ndarray:
    """DIN 45692 sharpness [acum] of each frame of a time-varying loudness, as
    ``mosqito.sq_metrics.sharpness_din_from_loudness(N, N_specific, "din")``.

    ``S = 0.11 Σ_z N'(z) g(z) z Δz / N`` with ``g = 1`` up to 15.8 Bark and
    ``g = 0.15 exp(0.42 (z − 15.8)) + 0.85`` above; 0 where ``N < 0.1`` sone.
    """
    N = np.ascontiguousarray(N, dtype=np.float64)
    spec = np.ascontiguousarray(N_specific, dtype=np.float64)
    if N.ndim != 1 or spec.shape != (BARK.size, N.size):
        raise ValueError(f"N_specific must have shape ({BARK.size}, {N.size}) to go with N, "
                         f"got {spec.shape}")
    return _sharpness(N, spec, _G_DIN, BARK)


def sharpness_din_tv(signal: np.ndarray, fs: int = SAMPLE_RATE, skip: float = 0.0):
    """DIN 45692 sharpness over time, as ``mosqito.sq_metrics.sharpness_din_tv``:
    ``(S, time_axis)`` from the frame nearest ``skip`` seconds on."""
    N, spec, _, t = loudness_zwtv(signal, fs)
    cut = int(np.argmin(np.abs(t - skip)))
    return sharpness_din(N, spec)[cut:], t[cut:]


@dataclasses.dataclass(frozen=True)
class Loudness:
    """Loudness and sharpness of one sound (module docstring: definitions).

    Attributes
    ----------
    loudness_sone : float
        ``N5`` [sone].
    sharpness_acum : float
        Mean DIN 45692 sharpness [acum] over the frames with loudness.
    time_s, loudness_t : ndarray
        The time-varying loudness ``N(t)`` [sone], every 2 ms.
    """

    loudness_sone: float
    sharpness_acum: float
    time_s: np.ndarray
    loudness_t: np.ndarray


def loudness(pressure_pa: np.ndarray, fs: int = SAMPLE_RATE) -> Loudness:
    """Loudness ``N5`` [sone] and mean sharpness [acum] of a sound-pressure signal [Pa].

    Parameters
    ----------
    pressure_pa : ndarray
        Sound pressure at the listener [Pa], sampled at ``fs``; at least 0.1 s long.
    fs : int
        48 000 Hz (ISO 532-1).
    """
    p = _check_pressure(pressure_pa)
    if not np.any(p):
        return _silence(p.size)
    N, spec, _, t = loudness_zwtv(p, fs)
    return _single_numbers(N, spec, t)


def _check_pressure(pressure_pa) -> np.ndarray:
    p = np.asarray(pressure_pa, dtype=np.float64)
    if p.ndim != 1 or p.size < 0.1 * SAMPLE_RATE:
        raise ValueError(f"pressure_pa must be a signal of at least 0.1 s at {SAMPLE_RATE} Hz, "
                         f"got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("pressure_pa must be finite")
    return p


def _silence(n: int) -> Loudness:
    t = np.arange(n // 96) * 0.002
    return Loudness(0.0, 0.0, t, np.zeros(t.size))


def _single_numbers(N: np.ndarray, spec: np.ndarray, t: np.ndarray) -> Loudness:
    keep = t >= SKIP_S
    n5 = float(np.percentile(N[keep], 95)) if np.any(keep) else float(np.percentile(N, 95))
    S = sharpness_din(N, spec)
    heard = keep & (N > 0)
    sharp = float(np.mean(S[heard])) if np.any(heard) else 0.0
    return Loudness(n5, sharp, t, N)


def band_levels(pressure_pa: np.ndarray, fs: int = SAMPLE_RATE) -> np.ndarray:
    """ISO 532-1's third-octave band levels [dB] of a sound pressure [Pa] (stage 1), shape
    ``(28, level samples)`` every 0.5 ms: the input of :func:`loudness_of_levels`."""
    p = _check_pressure(pressure_pa)
    x = _check_signal(p, fs)
    return _band_levels(x, _BANK, _FLOOR, _I_REF, _DECIMATE)


def sum_levels(levels: list) -> np.ndarray:
    """Band levels of incoherent sources together: the band intensities added, sample by
    sample (one source's levels are returned as they are)."""
    if len(levels) == 1:
        return levels[0]
    floor = _FLOOR / _I_REF
    total = sum(10.0 ** (np.asarray(lv) / 10.0) - floor for lv in levels) + floor
    return 10.0 * np.log10(total)


def loudness_of_levels(levels: np.ndarray, samples: int) -> Loudness:
    """Loudness and sharpness (as :func:`loudness`) from band levels of :func:`band_levels` or
    :func:`sum_levels`, of a sound ``samples`` long at 48 kHz."""
    N, spec, low = _zwtv_levels(np.ascontiguousarray(levels, dtype=np.float64), _RAP, _DLL,
                                _LTQ, _A0, _DCB, _MP1, _DECAY, _ZUP, _RNS, _RNS_SCALED, _USL,
                                _ZUP_STEP, _WEIGHT_POLES, *_WEIGHTS)
    if low > MAX_LOW_LEVEL_DB:
        raise ValueError(f"signal has a third-octave level of {low:.1f} dB below 315 Hz; the "
                         f"allowed range is up to {MAX_LOW_LEVEL_DB:g} dB (ISO 532-1's range)")
    frames = (samples + _DECIMATE - 1) // _DECIMATE
    t = np.linspace(0, samples / SAMPLE_RATE, num=frames)[::_OUT_EVERY]
    return _single_numbers(N, spec, t)


def loudness_incoherent(pressures: list, fs: int = SAMPLE_RATE) -> Loudness:
    """Loudness and sharpness of incoherent sources heard together (module docstring).

    Each signal's third-octave band intensities are added before the rest of ISO 532-1, so
    their phases never cancel; silent signals add nothing.  Of one signal it is
    :func:`loudness` exactly.  The signals are sound pressures [Pa] of equal length at ``fs``.
    """
    ps = [_check_pressure(p) for p in pressures]
    if not ps or any(p.size != ps[0].size for p in ps):
        raise ValueError(f"pressures must be 1 or more signals of equal length, got "
                         f"{[p.size for p in ps]} samples")
    heard = [p for p in ps if np.any(p)]
    if not heard:
        return _silence(ps[0].size)
    return loudness_of_levels(sum_levels([band_levels(p, fs) for p in heard]), ps[0].size)


__all__ = ["Loudness", "loudness", "loudness_incoherent", "band_levels", "sum_levels",
           "loudness_of_levels", "loudness_zwtv", "sharpness_din", "sharpness_din_tv",
           "SAMPLE_RATE", "DEFAULT_TRANSFER_PA_PER_NS", "SKIP_S", "BARK"]
