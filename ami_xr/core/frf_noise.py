"""Noise of an FRF per line, on plain arrays (numpy only): what ``ami_xr.dsp.noise_model`` wraps.

Two estimates of ``sigma(f) = sqrt(E|H_est(f) - H(f)|^2)``, the standard deviation of the complex
FRF estimate at each frequency line (real and imaginary parts each carry ``sigma^2 / 2``):

* :func:`coherence_noise_std` -- from the averaged spectra of the estimate (``ami_xr.frf``,
  ``ami_xr.impact_frf``): the random-error formulas of Bendat & Piersol (*Random Data*, 4th ed.,
  2010, ch. 9, random errors of frequency response function estimates: normalized error of the
  gain and standard deviation of the phase, both ``sqrt(1 - coh) / (|gamma| sqrt(2 n_d))``);
  the sum of the two (squared, times ``|H|^2``) is the variance of the complex estimate::

      sigma^2 = (1 - coh) |H|^2 / (coh (n_d - q))        one force (q = 1): H1, H2, Hv
      sigma_ip^2 = (1 - coh_p) Gyy_p [Gff^-1]_ii / (n_d - q)   q forces (MIMO H1; coh multiple)

  For H1 the two lines agree (``|H1|^2 = coh Gyy / Gff``); the second is the covariance of the
  least-squares solution ``Gfy = Gff H`` over ``n_d`` segments. ``n_d - q`` instead of Bendat &
  Piersol's ``n_d``: the coherence is itself estimated from the same ``n_d`` segments, and the
  residual spectrum ``(1 - coh) Gyy`` has ``n_d - q`` degrees of freedom (its expectation is
  ``(n_d - q) / n_d`` of the true noise spectrum), so the plug-in formula with ``n_d`` is low by
  ``sqrt(n_d / (n_d - q))`` -- 22 % for three hits. For H2 and Hv the first-order (high-coherence)
  error is that of H1, evaluated with their own ``|H|``. ``n_d`` is the effective number of
  independent averages (:func:`effective_averages`: overlapping segments and exponential averaging
  count less than their number).
* :func:`roughness_noise_std` -- from the FRF alone (a bare FRF from a file): the k-th difference
  along frequency annihilates everything that is a polynomial of degree < k over k + 1 lines (the
  modal part, where it is smooth on that scale) and multiplies white noise of std ``sigma`` by
  ``sqrt(binomial(2k, k))``; a running median of ``|diff_k|`` over a window of lines, divided by
  ``sqrt(ln 2 binomial(2k, k))`` (the median of a complex Gaussian's modulus is
  ``sigma sqrt(ln 2)``), is a robust (MAD-type) estimate of ``sigma`` that follows noise varying
  across the band and ignores the few lines at a sharp resonance where the modal part is not
  smooth.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.ndimage

from ami_xr.errors import AmiXrValueError

ROUGHNESS_ORDER = 4  # k: 24 / d^5 of a pole's peak left d lines away; even, so centred on a line
BLOCK_QUANTILE = 0.15  # block_roughness_std: the quietest lines of a block are the noise's
ROUGHNESS_WINDOW = 65  # lines of the running median: ~14 % per-line scatter, noise may vary ~2x
# |difference| above _OUTLIER running medians is not noise (P = 2^-(_OUTLIER^2) for noise); the
# running median is recomputed without such lines _OUTLIER_PASSES times
_OUTLIER = 3.0
_OUTLIER_PASSES = 2


def effective_averages(
    window: np.ndarray, step: int, count: int, average: str = "linear", n_average: int = 8
) -> float:
    """Effective number of independent averages of ``count`` Welch segments.

    Segment ``s`` enters the average with weight ``a_s`` (linear: ``1 / count``; exponential with
    time constant ``n_average``: the weights of ``ami_xr.dsp.spectral.WelchAccumulator``'s
    recursion) and segments ``j`` apart are correlated by ``rho_j = sum w(n) w(n + j step) /
    sum w^2`` (the window ``window`` of ``nperseg`` samples, segments ``step`` samples apart), so
    the variance of an averaged cross-spectrum falls as ``1 / n_eff`` with (Welch 1967)::

        n_eff = 1 / sum_{s, s'} a_s a_s' rho_{|s - s'|}^2

    ``count`` for linear averaging of non-overlapping segments.
    """
    count = int(count)
    if count < 1:
        return 0.0
    w = np.asarray(window, dtype=np.float64)
    n = w.size
    if average == "exponential" and count > n_average:
        decay = 1.0 - 1.0 / n_average
        a = np.empty(count)
        a[:n_average] = decay ** (count - n_average) / n_average
        a[n_average:] = decay ** np.arange(count - n_average - 1, -1, -1) / n_average
    else:
        a = np.full(count, 1.0 / count)
    total = float(np.sum(a * a))
    energy = float(np.sum(w * w))
    lag = 1
    while lag * step < n and lag < count and energy > 0.0:
        rho = float(np.sum(w[: n - lag * step] * w[lag * step :])) / energy
        total += 2.0 * rho * rho * float(np.sum(a[:-lag] * a[lag:]))
        lag += 1
    return 1.0 / total


def coherence_noise_std(
    frf: np.ndarray,
    coherence: np.ndarray,
    gff: np.ndarray,
    gyy: np.ndarray,
    n_eff: float,
    estimator: str = "H1",
) -> np.ndarray:
    """Standard deviation of the complex FRF estimate per line from its spectra (module docstring).

    Parameters
    ----------
    frf : ndarray, complex, shape (ref, point, frequency)
    coherence : ndarray, shape (point, frequency)
        Ordinary (one force) or multiple coherence of the estimate.
    gff : ndarray, complex, shape (ref, ref, frequency)
        Averaged force cross-spectral matrix.
    gyy : ndarray, shape (point, frequency)
        Averaged response autospectra.
    n_eff : float
        Effective number of averages (:func:`effective_averages`); must exceed ``ref``.
    estimator : {"H1", "H2", "Hv"}

    Returns
    -------
    ndarray, float, shape (ref, point, frequency); NaN where the coherence is undefined.
    """
    q = gff.shape[0]
    dof = float(n_eff) - q
    if not dof > 0.0:
        raise AmiXrValueError(
            f"n_eff: the coherence formula needs more than {q} effective averages, got {n_eff}"
        )
    coh = np.clip(np.asarray(coherence, dtype=np.float64), 0.0, 1.0)
    if estimator == "H1":
        finite = np.all(np.isfinite(gff), axis=(0, 1))
        inv = np.full(gff.shape, np.nan, dtype=np.complex128)
        mats = np.moveaxis(gff[..., finite], -1, 0)
        ok = np.abs(np.linalg.det(mats)) > 0.0 if mats.size else np.zeros(0, bool)
        inv_f = np.full(mats.shape, np.nan, dtype=np.complex128)
        if ok.any():
            inv_f[ok] = np.linalg.inv(mats[ok])
        inv[..., finite] = np.moveaxis(inv_f, 0, -1)
        inv_diag = np.real(np.einsum("iik->ik", inv))
        var = (1.0 - coh)[None] * np.asarray(gyy)[None] * inv_diag[:, None, :] / dof
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            var = (1.0 - coh)[None] * np.abs(frf) ** 2 / (coh[None] * dof)
    return np.sqrt(np.maximum(var, 0.0))


def check_roughness(order, window, n_frequency: int) -> None:
    """Raise :class:`AmiXrValueError` naming ``order`` or ``window`` (or ``frf`` when there are
    too few lines) unless :func:`roughness_noise_std` can run on ``n_frequency`` lines."""
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order < 2:
        raise AmiXrValueError(f"order: expected an even integer >= 2, got {order!r}")
    if order % 2:
        raise AmiXrValueError(f"order: expected an even integer (centred on a line), got {order}")
    if isinstance(window, bool) or not isinstance(window, (int, np.integer)) or window < 1:
        raise AmiXrValueError(f"window: expected an odd integer >= 1, got {window!r}")
    if window % 2 == 0:
        raise AmiXrValueError(f"window: expected an odd number of lines, got {window}")
    if n_frequency <= order:
        raise AmiXrValueError(
            f"frf: expected more than order={order} frequency lines, got {n_frequency}"
        )


def roughness_noise_std(
    frf: np.ndarray, order: int = ROUGHNESS_ORDER, window: int = ROUGHNESS_WINDOW
) -> np.ndarray:
    """Noise std per line of ``frf`` (..., frequency) from the roughness between adjacent lines.

    ``d[n] = sum_j (-1)^j binomial(order, j) H[n - order/2 + j]`` (centred on line ``n``; the
    ``order/2`` lines at each end repeat the nearest difference), then ``sigma[n] =
    median_{|m - n| <= window // 2} |d[m]| / sqrt(ln 2 binomial(2 order, order))`` (windows
    reflected at the band edges), the median taken without outliers: differences that are not
    finite, then (twice) those above 3 times the running median (noise exceeds that with
    probability 2^-9; a sharp resonance's lines do). The result is NaN where more than half of a
    window's differences are not finite.
    Assumes uniformly spaced lines.

    Parameters
    ----------
    frf : ndarray, complex, shape (..., n_frequency)
    order : int
        Even difference order ``k >= 2``; ``n_frequency`` must exceed it.
    window : int
        Odd number of lines of the running median (shortened to the band if longer).
    """
    h = np.asarray(frf)
    nf = h.shape[-1] if h.ndim else 0
    check_roughness(order, window, nf)
    d = np.diff(h.astype(np.complex128, copy=False), n=order, axis=-1)
    half = order // 2
    pad = [(0, 0)] * (d.ndim - 1) + [(half, half)]
    r = np.pad(np.abs(d), pad, mode="edge")
    window = int(min(window, nf if nf % 2 else nf - 1))
    size = (1,) * (r.ndim - 1) + (window,)
    # outliers (non-finite lines; then lines above OUTLIER times the running median) become 0 and
    # inf in turn, so that the median of a window is that of its other lines
    alternate = np.broadcast_to(np.arange(nf) % 2 == 0, r.shape)
    bad = ~np.isfinite(r)
    missing = scipy.ndimage.uniform_filter(bad.astype(np.float64), size=size, mode="reflect")
    med = np.full(r.shape, np.inf)
    for _ in range(1 + _OUTLIER_PASSES):
        bad |= r > _OUTLIER * med
        med = scipy.ndimage.median_filter(
            np.where(bad, np.where(alternate, 0.0, np.inf), r), size=size, mode="reflect"
        )
    sigma = med / math.sqrt(math.log(2.0) * math.comb(2 * order, order))
    sigma[(missing > 0.5) | ~np.isfinite(sigma)] = np.nan
    return sigma


def coherence_model(estimator: str, n_ref: int, n_eff: float, count: int) -> str:
    """The ``noise_model`` attribute of :func:`coherence_noise_std`'s result."""
    formula = (
        "(1 - coh) Gyy [Gff^-1]_ii / (n_d - q)"
        if estimator == "H1"
        else "(1 - coh) |H|^2 / (coh (n_d - q))"
    )
    return (
        f"coherence (Bendat & Piersol, Random Data, ch. 9 random error of H): var({estimator}) = "
        f"{formula}, n_d={n_eff:.4g} effective averages of {count} segments, q={n_ref}"
    )


def roughness_model(order: int = ROUGHNESS_ORDER, window: int = ROUGHNESS_WINDOW, reason="") -> str:
    """The ``noise_model`` attribute of :func:`roughness_noise_std`'s result."""
    text = (
        f"roughness: running median over {window} lines of |difference of order {order}| / "
        f"sqrt(ln 2 binomial({2 * order}, {order}))"
    )
    return f"{text} ({reason})" if reason else text


def _block_quantile(r: np.ndarray, edges: np.ndarray, q: float) -> np.ndarray:
    """The ``q``-quantile (numpy's linear rule) of the finite values of each row of ``r`` (R, L)
    in each block ``edges[b]:edges[b + 1]``, (R, n_block); NaN for a block without one. One
    sort of all blocks at once (``nanquantile`` loops in Python per row)."""
    lo, hi = edges[:-1], edges[1:]
    width = int(np.max(hi - lo))
    idx = lo[:, None] + np.arange(width)[None, :]
    pad = idx >= hi[:, None]
    x = r[:, np.minimum(idx, r.shape[1] - 1)]  # (R, n_block, width)
    x = np.where(pad[None] | ~np.isfinite(x), np.inf, x)
    x.sort(axis=-1)
    count = np.sum(np.isfinite(x), axis=-1)
    pos = q * np.maximum(count - 1, 0)
    below = np.floor(pos).astype(int)
    above = np.minimum(below + 1, np.maximum(count - 1, 0))
    a = np.take_along_axis(x, below[..., None], -1)[..., 0]
    b = np.take_along_axis(x, above[..., None], -1)[..., 0]
    with np.errstate(invalid="ignore"):
        out = a + (pos - below) * (b - a)
    return np.where(count > 0, out, np.nan)


def block_roughness_std(
    frf: np.ndarray, order: int = ROUGHNESS_ORDER, block: int = 64, quantile: float = BLOCK_QUANTILE
) -> np.ndarray:
    """A cheap roughness estimate of the noise std per line (O(lines), for deciding and
    weighting inside ``identify``): the differences of :func:`roughness_noise_std`, the
    ``quantile`` of their modulus over consecutive blocks of about ``block`` lines, scaled to a
    standard deviation (the q-quantile of a complex Gaussian's modulus is ``sigma sqrt(-ln(1 -
    q))``), interpolated linearly between block centres. A low quantile, not the median: near a
    resonance the modal part is not smooth on the scale of ``order`` lines and its difference
    adds to the noise's, only ever upwards; the quietest lines of a block are those far from
    every peak (a peak of bandwidth ``b`` lines leaves ``~24 b / d^5`` of its height in the
    difference ``d`` lines away), so the estimate follows the noise where the noise is far
    below the FRF (receptance with noise white in acceleration, at high frequency), where a
    median follows the peaks. ``frf`` (..., n_frequency) with at least ``order + 1`` lines; NaN
    lines are left out."""
    h = np.asarray(frf, dtype=np.complex128)
    shape = h.shape
    h = h.reshape(-1, shape[-1])
    nf = shape[-1]
    check_roughness(order, 1, nf)
    half = order // 2
    r = np.pad(np.abs(np.diff(h, n=order, axis=-1)), [(0, 0), (half, half)], mode="edge")
    n_block = max(nf // max(int(block), 1), 1)
    edges = np.linspace(0, nf, n_block + 1).astype(int)
    centres = 0.5 * (edges[:-1] + edges[1:] - 1)
    med = _block_quantile(r, edges, quantile)
    if n_block == 1:
        out = np.repeat(med, nf, axis=1)
    else:
        lines = np.arange(nf)
        out = np.stack([np.interp(lines, centres, m) for m in med])
    sigma = out / math.sqrt(-math.log(1.0 - quantile) * math.comb(2 * order, order))
    return sigma.reshape(shape)


def whitening_losses(
    frf: np.ndarray, frequency: np.ndarray, shifts, sigma: np.ndarray | None = None
) -> tuple[dict[int, float], dict[int, np.ndarray]]:
    """How much unweighted least squares loses to the noise's variation along frequency, for the
    FRFs (P, L) multiplied by ``(i w)^k`` for each ``k`` in ``shifts``, and the noise std of each.

    The noise std per point and line of ``frf (i w)^k`` is :func:`block_roughness_std` of it,
    estimated in each quantity anew (a steep trend within one block of the estimate -- receptance
    with noise white in acceleration falls 4096-fold over its first 64 lines -- is followed by
    none of them, but it is flat in the quantity where the noise is white); with ``sigma`` (P,
    L) given (from the coherence) it is ``sigma w^k``. The loss of one point is ``mean(s^2)
    mean(1 / s^2)`` over its lines above 0 Hz (the variance of an unweighted least-squares
    estimate over that of the weighted one, for a parameter that every line informs alike: 1
    for white noise, larger the more the level varies), the loss of a shift the median over
    points. Lines where the std is not finite and positive are left out.

    Returns ``({k: loss}, {k: std (P, L') on the lines above 0 Hz})``.
    """
    h = np.asarray(frf).reshape(-1, np.shape(frf)[-1])
    f = np.asarray(frequency, dtype=np.float64)
    use = f > 0
    w = 2.0 * np.pi * f[use]
    losses, stds = {}, {}
    for k in shifts:
        if sigma is not None:
            x = np.asarray(sigma, dtype=np.float64).reshape(h.shape)[:, use] * w[None, :] ** k
        else:
            # unit-free: w / its median, so that huge or tiny units do not overflow
            x = block_roughness_std(h[:, use] * (1j * w / np.median(w))[None, :] ** k)
            x = x * np.median(w) ** k
        ok = np.isfinite(x) & (x > 0)
        loss = []
        for row, good in zip(x, ok, strict=True):
            if good.sum() < 8:
                continue
            v = row[good] ** 2
            v = v / np.median(v)
            loss.append(float(np.mean(v) * np.mean(1.0 / v)))
        losses[int(k)] = float(np.median(loss)) if loss else 1.0
        stds[int(k)] = x
    return losses, stds


def noise_dominated_share(
    frf: np.ndarray, block: int = 64, fourth: np.ndarray | None = None
) -> float:
    """The share of (row, block) estimates of :func:`block_roughness_std` that measure noise,
    not the FRF's own curvature: for white noise the estimates from differences of order 4 and
    6 agree (each is scaled to the noise std), for a smooth function the 6th difference is
    orders of magnitude below the 4th (measured: ratio 1.00-1.02 on noisy random systems at 1 %,
    0.00-0.01 noise-free). An estimate counts as noise where the ratio exceeds 0.7.
    ``fourth``: the order-4 estimate of ``frf`` when the caller has it."""
    h = np.asarray(frf).reshape(-1, np.shape(frf)[-1])
    if h.shape[-1] <= 6:
        return 0.0
    a = block_roughness_std(h, 4, block) if fourth is None else np.reshape(fourth, h.shape)
    b = block_roughness_std(h, 6, block)
    step = max(int(block), 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = (b / a)[:, step // 2 :: step]
    return float(np.mean(r > 0.7)) if r.size else 0.0


SMOOTH_WIDTH = 0.02  # smoothed_std: blocks of 2 % of the frequency ...
SMOOTH_LINES = 8  # ... and at least this many lines


def smoothing_edges(
    frequency: np.ndarray, width: float = SMOOTH_WIDTH, min_lines: int = SMOOTH_LINES
) -> np.ndarray:
    """Block edges (line indices, first 0, last ``L``) of :func:`smoothed_std`: consecutive
    blocks of ``max(min_lines, width f / df)`` lines (``f`` at the block's start, ``df`` the
    median line spacing), a short last block joined to the one before."""
    f = np.abs(np.asarray(frequency, dtype=np.float64))
    n = f.size
    df = float(np.median(np.diff(f))) if n > 1 else 0.0
    edges, i = [0], 0
    while i < n:
        step = min_lines if not df > 0 else max(min_lines, math.ceil(width * f[i] / df))
        i = min(i + step, n)
        edges.append(i)
    if len(edges) > 2 and edges[-1] - edges[-2] < min_lines:
        del edges[-2]
    return np.asarray(edges, dtype=np.int64)


def smoothed_std(
    sd: np.ndarray,
    frequency: np.ndarray,
    width: float = SMOOTH_WIDTH,
    min_lines: int = SMOOTH_LINES,
) -> np.ndarray:
    """A noise std per line (..., L) floored at its local level along frequency: each line
    keeps ``max(sd, level)``, the level the median of ``log sd`` over the blocks of
    :func:`smoothing_edges`, interpolated linearly (in log) between block centres.

    Why: the coherence formula gives each line its own estimate, itself random (the coherence
    of ``n_d`` averages scatters by tens of per cent); weighting the lines by it lets the few
    lines whose noise came out low by chance decide a fit (an underestimated variance weighs a
    line up, an overestimated one only wastes a little of it). The noise's level changes slowly
    along frequency (a force spectrum rolling off, sensor noise in one quantity), on scales
    wider than a few per cent of the frequency, so a block median keeps it; in log, so that a
    factor above and below weigh alike. Lines above the level keep their own estimate: at a
    peak the window's leakage lowers the coherence, a model error the fit should not be
    weighted to follow. Lines with no finite positive value get the level of their
    neighbours; a row with none stays NaN.
    """
    x = np.asarray(sd, dtype=np.float64)
    out = local_level(x, frequency, width, min_lines)
    # a floor, not a replacement: a line above the local level keeps its own estimate (leakage
    # at an under-resolved peak raises 1 - coh there: that model error is real, and weighting
    # the peak's lines up split a 3-line-wide simulated mode in two)
    return np.where(np.isfinite(x) & (x > out), x, out)


def local_level(
    sd: np.ndarray,
    frequency: np.ndarray,
    width: float = SMOOTH_WIDTH,
    min_lines: int = SMOOTH_LINES,
) -> np.ndarray:
    """The local level of a noise std (..., L) along frequency: the median of ``log sd`` over
    the blocks of :func:`smoothing_edges`, interpolated linearly (in log) between the block
    centres (NaN for a row with no finite positive value)."""
    x = np.asarray(sd, dtype=np.float64)
    shape = x.shape
    x = x.reshape(-1, shape[-1])
    with np.errstate(divide="ignore", invalid="ignore"):
        logs = np.where(np.isfinite(x) & (x > 0), np.log(x), np.nan)
    edges = smoothing_edges(frequency, width, min_lines)
    centres = 0.5 * (edges[:-1] + edges[1:] - 1)
    med = np.full((x.shape[0], edges.size - 1), np.nan)
    for b in range(edges.size - 1):
        block = logs[:, edges[b] : edges[b + 1]]
        has = np.isfinite(block).any(axis=1)
        if has.any():
            med[has, b] = np.nanmedian(block[has], axis=1)
    lines = np.arange(shape[-1])
    out = np.full(x.shape, np.nan)
    for r, row in enumerate(med):
        ok = np.isfinite(row)
        if ok.any():
            out[r] = np.exp(np.interp(lines, centres[ok], row[ok]))
    return out.reshape(shape)


def smoothing_model(width: float = SMOOTH_WIDTH, min_lines: int = SMOOTH_LINES) -> str:
    """How :func:`smoothed_std` smoothed a noise model (for the ``noise_model_source`` record)."""
    return (
        f"smoothed along frequency (each line at least the median of log std over blocks of "
        f"{100 * width:g} % of f, at least {min_lines} lines)"
    )
