"""What every feature search takes and returns, and the small array kernels they share.

All searches have the signature ``search(profiles: Profiles, config: SearchConfig) -> Edges``:
they read a whole frame's profiles as one ``(links, samplers, points)`` array and return, per
profile, the positions of both phalanx boundaries along it (in samples: index 0 is the first
sample, ``profiles.centre`` the predicted axis), a strength and a validity flag per boundary.
Boundary 0 lies towards smaller sample indices, boundary 1 towards larger ones.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import cv2
import numpy as np

from .._xy import clip_index

__all__ = ["Profiles", "Edges", "parabola_vertex", "simple_derivative", "gaussian_derivative",
           "derivative_kernel", "masked_argmax", "width_template", "correlate_shifts", "edges_about_centres",
           "sample_at", "boundary_peaks", "per_pixel", "pad_last", "windows_last", "correlate_last"]


def pad_last(a: np.ndarray, h: int, *, edge: bool = False) -> np.ndarray:
    """``np.pad`` of the last axis by ``h`` on both sides, with zeros (False) or, with ``edge``,
    the end values: the same array, without ``np.pad``'s per-call Python overhead (it runs
    several times on every profile set of a frame)."""
    n = a.shape[-1]
    out = np.empty(a.shape[:-1] + (n + 2 * h,), a.dtype)
    out[..., h:h + n] = a
    if edge and n:
        out[..., :h] = a[..., :1]
        out[..., h + n:] = a[..., -1:]
    else:
        out[..., :h] = 0
        out[..., h + n:] = 0
    return out


def windows_last(a: np.ndarray, n: int) -> np.ndarray:
    """``sliding_window_view(a, n, axis=-1)`` of a C-contiguous ``a`` (a read-only view of shape
    ``a.shape[:-1] + (a.shape[-1] - n + 1, n)``), built directly: the same strides, so the same
    products downstream, without the tens of microseconds of the general function's checks."""
    win = np.ndarray(a.shape[:-1] + (a.shape[-1] - n + 1, n), a.dtype, buffer=a, strides=a.strides + a.strides[-1:])
    win.flags.writeable = False
    return win


# OpenCV's filter2D switches to a DFT (other roundings) from this many kernel taps for float64.
_DIRECT_TAPS = 50


def correlate_last(a: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """``out[..., i] = sum_j kernel[j] a[..., i + j]`` for float64 ``a`` (..., m), shape (..., m - k + 1):
    ``windows_last(a, k) @ kernel`` with the same bits. NumPy's matmul cannot hand overlapping windows
    to BLAS when there are two windows or more and sums them in its own loop, in order of ``j`` from
    0; OpenCV's direct ``filter2D`` sums the products in the same order, several outputs at a time,
    several times faster (tested bit for bit against the matmul in tests/test_image_kernels.py). A
    single window (which NumPy hands to BLAS) and kernels of ``_DIRECT_TAPS`` taps or more (which
    OpenCV would filter by DFT) take the matmul."""
    k = len(kernel)
    m = a.shape[-1]
    if m - k < 1 or k >= _DIRECT_TAPS or a.size == 0 or a.dtype != np.float64:
        return windows_last(np.ascontiguousarray(a), k) @ kernel
    rows = np.ascontiguousarray(a).reshape(-1, m)
    out = cv2.filter2D(rows, cv2.CV_64F, np.asarray(kernel, np.float64)[None, :], anchor=(0, 0),
                       borderType=cv2.BORDER_CONSTANT)
    return out[:, :m - k + 1].reshape(a.shape[:-1] + (m - k + 1,))


@dataclasses.dataclass(frozen=True)
class Profiles:
    """A frame's link profiles and what a search may know about them.

    Attributes:
        values: (links, samplers, points) intensities in grey levels (0 where not usable).
        usable: (links, samplers, points) the sample lies inside the image and is finite.
        window: (links, samplers, points) the sample lies in the link's visibility window
            (thesis §4.3.3); always a subset of ``usable``.
        centre: sample index of the predicted axis, ``(points - 1) / 2``.
        radius: predicted radius in samples (the same for every link).
        spacing_px: (links,) pixels between neighbouring samples.
        templates: (links, samplers, points) stored profiles (thesis §4.3.1), or None.
        template_valid: (links,) a template is stored for the link.
        template_mask: (links, samplers, points) the template samples that showed the link when
            it was taken (None: all of them).
        boundary_clear: (links, samplers, 2) no other link's outline lies just outside each
            boundary, so the edge there is the link's own against the background (None: all).
    """

    values: np.ndarray
    usable: np.ndarray
    window: np.ndarray
    centre: float
    radius: float
    spacing_px: np.ndarray
    templates: np.ndarray | None = None
    template_valid: np.ndarray | None = None
    template_mask: np.ndarray | None = None
    boundary_clear: np.ndarray | None = None

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.values.shape

    def max_shift(self, shift_r: float) -> int:
        """A displacement of ``shift_r`` radii in whole samples (at least 1)."""
        return max(1, int(np.ceil(shift_r * self.radius)))


@dataclasses.dataclass(frozen=True)
class Edges:
    """Boundary positions found on every profile.

    Attributes:
        pos: (links, samplers, 2) positions along the profile, samples (boundary 0, boundary 1).
        strength: (links, samplers, 2) edge strength (grey levels per pixel for derivative
            searches, template contrast in grey levels for wssd).
        valid: (links, samplers, 2) the boundary was found.
        surface: optional (links, samplers, shifts) correlation or WSSD surface (diagnostics).
        shifts: optional (shifts,) displacement in samples of each surface column.
    """

    pos: np.ndarray
    strength: np.ndarray
    valid: np.ndarray
    surface: np.ndarray | None = None
    shifts: np.ndarray | None = None


def per_pixel(values: np.ndarray, spacing_px: np.ndarray) -> np.ndarray:
    """Per-sample derivatives of (links, samplers) profiles as grey levels per pixel; a link without
    samplers (spacing 0) gets 0."""
    safe = np.where(spacing_px > 0, spacing_px, np.inf)  # Guard: 0 spacing means no samplers
    return values / safe[:, None]


def parabola_vertex(ym: np.ndarray, y0: np.ndarray, yp: np.ndarray) -> np.ndarray:
    """Offset in (-0.5, 0.5) of the vertex of the parabola through (-1, ym), (0, y0), (1, yp).

    Works for maxima and minima; a flat or degenerate triple gives 0.
    """
    den = ym - 2.0 * y0 + yp
    # Guard: a zero curvature (flat or linear triple) has no vertex; keep the integer position.
    curved = np.abs(den) > 1e-12
    off = np.where(curved, 0.5 * (ym - yp) / np.where(curved, den, 1.0), 0.0)
    return np.asarray(np.minimum(np.maximum(off, -0.5), 0.5))  # np.clip's values without its per-call checks


def simple_derivative(values: np.ndarray, usable: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Thesis eq. 11.1, ``D(k) = I(k+1) - I(k)``, located half way between the two samples.

    Returns:
        (D, D_valid, positions): D and its validity with shape (..., points - 1), and the sample
        position ``k + 0.5`` of each entry.
    """
    d = values[..., 1:] - values[..., :-1]
    ok = usable[..., 1:] & usable[..., :-1]
    return np.where(ok, d, 0.0), ok, np.arange(values.shape[-1] - 1) + 0.5


@functools.lru_cache(maxsize=32)
def derivative_kernel(sigma: float) -> np.ndarray:
    """Sampled Gaussian derivative (thesis §11.1.2), scaled so a unit ramp gives 1, as a
    correlation kernel (``out(k) = sum_i c_i I(k + i)``) of length ``2 ceil(3 sigma) + 1``
    (cached and read-only: it depends on the settings only)."""
    h = max(1, int(np.ceil(3.0 * sigma)))
    i = np.arange(-h, h + 1, dtype=float)
    c = i * np.exp(-0.5 * (i / sigma) ** 2)  # -dN/dk up to a constant: correlation form of the derivative
    return _read_only(c / np.sum(c * i))


def _read_only(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


def gaussian_derivative(values: np.ndarray, usable: np.ndarray, sigma: float
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Smoothed derivative by convolution with a Gaussian derivative (thesis §11.1.2).

    The profile ends are extended with their end values, as the thesis prescribes. An output
    sample is valid only when every input sample under the kernel is usable.

    Returns:
        (D, D_valid, positions) with shape (..., points) and positions ``0 .. points - 1``.
    """
    c = derivative_kernel(sigma)
    h = (len(c) - 1) // 2
    d = correlate_last(pad_last(values, h, edge=True), c)
    bad = pad_last(~usable, h, edge=True)
    n = values.shape[-1]
    hit = bad[..., : n].copy()  # any unusable sample under the kernel, as shifted ORs (no short-axis reduction)
    for i in range(1, len(c)):
        hit |= bad[..., i: i + n]
    ok = ~hit
    return np.where(ok, d, 0.0), ok, np.arange(values.shape[-1], dtype=float)


@functools.lru_cache(maxsize=64)
def row_starts(shape: tuple[int, ...]) -> np.ndarray:
    """(shape[:-1]) the flat index of each row's first entry in a C-ordered array of ``shape`` (cached
    per shape and read-only: a frame's arrays have the same few shapes every frame)."""
    n = shape[-1]
    return _read_only(np.arange(0, math.prod(shape), n).reshape(shape[:-1]))


def take_last(a: np.ndarray, k: np.ndarray) -> np.ndarray:
    """``a[..., k]`` with one index per row (``k`` of shape ``a.shape[:-1]``, or with one more axis
    of several indices per row): ``np.take_along_axis`` by flat indexing, without its overhead."""
    a = np.ascontiguousarray(a)
    base = row_starts(a.shape)
    return a.reshape(-1)[(base if k.ndim == base.ndim else base[..., None]) + k]


def masked_argmax(score: np.ndarray, allowed: np.ndarray, subsample: bool) -> tuple[np.ndarray, np.ndarray,
                                                                                      np.ndarray]:
    """Largest ``score`` along the last axis among ``allowed`` entries.

    Returns:
        (index, value, offset): integer index of the maximum (0 where nothing is allowed), its
        score (-inf where nothing is allowed) and the parabola vertex offset (0 without
        ``subsample`` or at the ends of the allowed run).
    """
    s = np.where(allowed, score, -np.inf)
    k = np.argmax(s, axis=-1)
    flat = s.reshape(-1)
    at = row_starts(s.shape) + k  # take_last's gathers, the rows found once
    val = flat[at]
    if not subsample:
        return k, val, np.zeros(k.shape)
    after = k > 0
    before = k < s.shape[-1] - 1
    sm, sp = flat[at - after], flat[at + before]  # the neighbours, clipped to the row
    inner = after & before & np.isfinite(sm) & np.isfinite(sp) & np.isfinite(val)
    off = np.where(inner, parabola_vertex(np.where(inner, sm, 0.0), np.where(inner, val, 0.0),
                                          np.where(inner, sp, 0.0)), 0.0)
    return k, val, off


@functools.lru_cache(maxsize=32)
def width_template(points: int, centre: float, width: float, sigma: float, sign: float) -> np.ndarray:
    """Synthetic derivative of an ideal phalanx profile (thesis §11.2.2): a positive and a negative
    peak (narrow Gaussian blobs of ``sigma`` samples, each summing to one, which puts a peak between
    samples) at ``centre ∓ width / 2``; the first peak is positive for ``sign = +1`` (bright hand).
    Cached and read-only: it depends on the settings only."""
    k = np.arange(points, dtype=float)
    s = max(sigma, 1e-3)
    left = np.exp(-0.5 * ((k - (centre - width / 2)) / s) ** 2)
    right = np.exp(-0.5 * ((k - (centre + width / 2)) / s) ** 2)
    return _read_only(sign * (left / left.sum() - right / right.sum()))


def correlate_shifts(d: np.ndarray, d_valid: np.ndarray, template: np.ndarray, max_shift: int
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Correlation of every row of ``d`` with ``template`` at displacements ``-S..S`` (thesis §11.2.2):
    ``C(s) = sum_j d(j + s) t(j)``, with ``d`` taken as 0 past its ends.

    Returns:
        (C, shifts): C with shape (..., 2 S + 1) and the displacement of each column.
    """
    S = int(max_shift)
    padded = pad_last(np.where(d_valid, d, 0.0), S)  # C(s) is the window of padded starting at s + S
    return correlate_last(padded, template), np.arange(-S, S + 1)


def edges_about_centres(centre_pos: np.ndarray, width: float) -> np.ndarray:
    """Boundary positions ``centre ∓ width / 2`` (thesis §4.3.2: edges extrapolated from the width)."""
    return np.stack([centre_pos - width / 2, centre_pos + width / 2], axis=-1)


def sample_at(curves: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """Linear interpolation of each curve (last axis) at a fractional index per curve (clipped)."""
    n = curves.shape[-1]
    p = np.minimum(np.maximum(pos, 0), n - 1)  # np.clip's values without its per-call checks
    k0 = clip_index(p.astype(int), 0, n - 2) if n > 1 else np.zeros(p.shape, int)  # p >= 0: the cast floors
    f = p - k0
    flat = np.ascontiguousarray(curves).reshape(-1)
    at = row_starts(curves.shape) + k0  # take_last's gathers, the rows found once
    a = flat[at]
    b = flat[at + 1] if n > 1 else a  # k0 + 1 <= n - 1
    return (1 - f) * a + f * b


def boundary_peaks(d: np.ndarray, d_valid: np.ndarray, positions: np.ndarray, ranges: tuple, profiles: Profiles,
                   sign: float, min_strength: float, subsample: bool) -> Edges:
    """Both boundaries as the strongest derivative of the right sign inside a range of positions.

    Boundary 0 is the strongest ``sign * d`` (a rising edge for a bright hand), boundary 1 the
    strongest ``-sign * d``; each only among valid derivatives whose position lies in its range.

    Args:
        d, d_valid: (links, samplers, k) derivative and validity.
        positions: (k,) sample position of each derivative entry.
        ranges: ((lo0, hi0), (lo1, hi1)) inclusive position limits, each broadcastable to
            (links, samplers, 1).
        profiles: the profiles (for the pixel spacing).
        sign: +1 for a bright hand, -1 for a dark one.
        min_strength: weakest accepted edge, grey levels per pixel.
        subsample: parabola refinement of each peak.
    """
    pos, strength, valid = [], [], []
    for side, (lo, hi) in enumerate(ranges):
        allowed = d_valid & (positions >= lo) & (positions <= hi)
        s = (sign if side == 0 else -sign) * d
        k, val, off = masked_argmax(s, allowed, subsample)
        found = np.isfinite(val)
        st = per_pixel(np.where(found, val, 0.0), profiles.spacing_px)
        pos.append(positions[k] + off * (positions[1] - positions[0] if len(positions) > 1 else 1.0))
        strength.append(st)
        valid.append(found & (st >= min_strength) & (st > 0))
    return Edges(pos=np.stack(pos, -1), strength=np.stack(strength, -1), valid=np.stack(valid, -1))
