"""Windowed SSD against stored templates (the thesis's proposed method, §4.3.1-4.3.2).

The only search built for occlusion. Each profile is compared with the template stored for it
from an earlier view, but only where the link is visible: the window function (thesis §4.3.3)
masks the template, ``m(j) = v(j) t(j)``, and the windowed SSD is taken over the window only
(§4.3.1); a template taken from a partly hidden view also masks its own hidden samples. Here the
template slides over the current profile, ``I(j + s)`` against ``t(j)``, and the sum is divided by
the number of terms, because near the ends of a profile some shifts see fewer samples. The
curves of one link side by side make a WSSD surface whose valley is a line (the phalanx is
straight). The valley is found as in §4.3.2:

1. start every profile at displacement 0 (the prediction);
2. step each displacement one sample against the sign of the surface's gradient there,
   ``y <- y - sign(g)``;
3. fit a PLLS line ``y = c0 + c1 x`` through the stepped points and round it to whole samples;
4. repeat 2-3 until the rounded line stops changing (or ``max_iter``).

With ``subsample`` each profile's displacement is then refined to the vertex of the parabola
through the surface's smallest value near the line and its neighbours, and a last PLLS line is
fitted through the refined points (not in the thesis, whose offsets are whole samples). The
boundaries are put one predicted radius either side of the valley line (edges extrapolated
from the phalanx width).
"""

from __future__ import annotations

import numpy as np

from .._config import SearchConfig
from .._regression import SINGULAR, normal_equations, plls
from .._xy import clip_index
from ._common import (
    Edges,
    Profiles,
    edges_about_centres,
    gaussian_derivative,
    masked_argmax,
    pad_last,
    parabola_vertex,
    per_pixel,
    row_starts,
    take_last,
    windows_last,
)

__all__ = ["wssd_valley", "wssd_surface"]


def wssd_surface(values: np.ndarray, usable: np.ndarray, templates: np.ndarray, window: np.ndarray, max_shift: int,
                 zero_mean: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean windowed squared difference of every profile against its template at every shift.

    ``WSSD(s) = mean over j with v(j) and I(j + s) usable of (I(j + s) - t(j))^2``; with
    ``zero_mean`` the mean of the difference over those j is taken out first (its variance), so
    an offset in brightness between profile and template costs nothing.

    Args:
        values, usable: (..., n) current profiles and their usable samples.
        templates: (..., n) stored templates.
        window: (..., n) visibility window (applied to the template).
        max_shift: S; shifts run over -S..S.

    Returns:
        (W, counts, shifts): W (..., 2 S + 1) (inf where no term counts), the number of terms of
        each entry, and the shifts.
    """
    S = int(max_shift)
    n = values.shape[-1]
    img = windows_last(pad_last(values, S), n)  # (..., 2S+1, n): I(j + s)
    # The terms that count as 0/1 factors: a masked difference times 0 is the 0 the sum skips and
    # times 1 is itself, so W has the same bits as masking by assignment. The factor multiplies
    # before the square, and the templates are zeroed outside their window, so no masked term is
    # an inf or a NaN (values are finite). The counts are the factors' sums.
    ok = windows_last(pad_last(usable, S), n) & window[..., None, :]
    diff = np.subtract(img, np.where(window, templates, 0.0)[..., None, :])
    np.multiply(diff, ok, out=diff)  # in place: the surface is the largest array of a frame
    counts = _count_last(ok)
    n_terms = np.maximum(counts, 1)
    mean_diff = diff.sum(-1) / n_terms if zero_mean else 0.0
    W = np.square(diff, out=diff).sum(-1) / n_terms
    if zero_mean:
        W = np.maximum(W - np.square(mean_diff), 0.0)   # Guard: rounding below 0 for a perfect match
    return np.where(counts > 0, W, np.inf), counts, np.arange(-S, S + 1)


def _count_last(b: np.ndarray) -> np.ndarray:
    """``b.sum(-1)`` of a C-contiguous boolean array: with a last axis of a multiple of 8 and at most
    255 entries, each row's bytes (0 or 1) are read 8 at a time as 64-bit words, the words added, and
    the 8 byte sums of the total added into its top byte by one multiplication (exact integers; five
    times faster than the sum or a matmul of 0/1 floats on the WSSD's (links, samplers, shifts, n))."""
    n = b.shape[-1]
    if n % 8 or n > 255 or not b.flags.c_contiguous or b.size == 0:
        return b.sum(-1)
    words = b.reshape(-1, n).view(np.uint64)  # (rows, n / 8): each byte one entry of b
    total = words[:, 0].copy()
    for i in range(1, n // 8):
        total += words[:, i]  # no byte overflows: each holds at most n / 8
    return ((total * np.uint64(0x0101010101010101)) >> np.uint64(56)).astype(int).reshape(b.shape[:-1])


def _descend(W: np.ndarray, curve_ok: np.ndarray, S: int, max_iter: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit-step valley descent with PLLS and rounding (§4.3.2), all links at once.

    Returns:
        (yhat, fit_ok): (links, samplers) integer displacements on the rounded line, and the links
        whose line could be fitted.
    """
    L, M, K = W.shape
    x = np.arange(M, dtype=float)
    # Non-finite entries (no term counted) become a wall higher than any real value, so the
    # gradient points away from them.
    finite = np.isfinite(W)
    wall = np.where(finite, W, -np.inf).max(initial=0.0) * 2 + 1.0
    Wf = np.where(finite, W, wall)
    yhat = np.zeros((L, M), int)
    fit_ok = curve_ok.sum(-1) >= 2
    active = fit_ok.copy()
    # The PLLS mask is the same every iteration: its normal matrix is built once (the same
    # arithmetic as :func:`plls`, so the lines are bit for bit the same).
    w = curve_ok.astype(float)
    xb = np.broadcast_to(x, (L, M))
    R, _ = normal_equations(xb, w, w)
    # solve_2x2's arithmetic with its matrix-only terms taken out of the loop (the same bits).
    det = R[..., 0, 0] * R[..., 1, 1] - R[..., 0, 1] * R[..., 1, 0]
    ok = np.abs(det) > SINGULAR * np.maximum((np.abs(R[..., 0, 0]) + np.abs(R[..., 1, 1])) ** 2, 1e-300)
    safe = np.where(ok, det, 1.0)
    r00, r01, r10, r11 = R[..., 0, 0], R[..., 0, 1], R[..., 1, 0], R[..., 1, 1]
    flat, base = Wf.reshape(-1), row_starts(Wf.shape)
    # Each link's next line depends on its own displacements only, so a link whose line comes
    # back to an earlier one cycles from there on: its line after ``max_iter`` steps is known at
    # once, and the link leaves the loop (the result is the same as iterating on). Earlier lines
    # are compared a whole row at a time, each row of displacements viewed as one opaque value.
    history = np.zeros((max_iter + 1, L, M), yhat.dtype)
    rows_seen = history.view(np.dtype((np.void, history.itemsize * M)))[..., 0]  # (steps, links)
    for n in range(max_iter):
        if not active.any():
            break
        k = yhat + S
        up = flat[base + np.minimum(k + 1, K - 1)]
        down = flat[base + np.maximum(k - 1, 0)]
        y = yhat - np.sign(up - down)
        b = np.where(curve_ok, y, 0.0)  # the PLLS weights are curve_ok as 0/1: w * b is b
        b0, b1 = b.sum(-1), (b * xb).sum(-1)
        c0 = np.where(ok, (r11 * b0 - r01 * b1) / safe, 0.0)
        c1 = np.where(ok, (r00 * b1 - r10 * b0) / safe, 0.0)
        new = np.minimum(np.maximum(np.rint(c0[:, None] + c1[:, None] * x), -S), S).astype(int)
        step = active & ok
        changed = np.any((new != yhat) & curve_ok, axis=-1)
        yhat = np.where(step[:, None], new, yhat)
        fit_ok = fit_ok & np.where(active, ok, True)
        active = step & changed
        history[n + 1] = yhat
        seen = (rows_seen[: n + 1] == rows_seen[n + 1]) & active  # (steps so far, links)
        if seen.any():
            yhat = yhat.copy()
            t = n + 1
            for link in np.nonzero(seen.any(0))[0]:
                t0 = int(np.nonzero(seen[:, link])[0][0])
                yhat[link] = history[t0 + (max_iter - t0) % (t - t0), link]
            active = active & ~seen.any(0)
    return yhat, fit_ok


def _refine(W: np.ndarray, yhat: np.ndarray, curve_ok: np.ndarray, S: int, subsample: bool
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sub-sample valley points near the rounded line and the last PLLS line through them.

    Returns:
        (y, fit_ok, wmin): the line's displacement at each profile, the links fitted and each
        profile's smallest WSSD near the line (inf where that minimum lies on the edge of the
        searched shifts).
    """
    L, M, K = W.shape
    x = np.arange(M, dtype=float)
    flat, base = np.ascontiguousarray(W).reshape(-1), row_starts(W.shape)  # take_last's gathers, rows found once
    idx = yhat + S
    near = idx[..., None] + np.arange(-2, 3)  # the five entries around the rounded line
    inside = (near >= 0) & (near < K)
    vals = np.where(inside, flat[base[..., None] + clip_index(near, 0, K - 1)], np.inf)
    j = np.argmin(vals, -1)
    k = clip_index(idx + j - 2, 0, K - 1)
    wmin = flat[base + k]
    y = (k - S).astype(float)
    if subsample:
        wm, wp = flat[base + clip_index(k - 1, 0, K - 1)], flat[base + clip_index(k + 1, 0, K - 1)]
        inner = (k > 0) & (k < K - 1) & np.isfinite(wm) & np.isfinite(wp) & np.isfinite(wmin)
        y = y + np.where(inner, parabola_vertex(np.where(inner, wm, 0.0), np.where(inner, wmin, 0.0),
                                                np.where(inner, wp, 0.0)), 0.0)
    # A minimum on the edge of the searched shifts is no valley: the phalanx lies farther away.
    use = curve_ok & np.isfinite(wmin) & (k > 0) & (k < K - 1)
    c, ok = plls(x, y, use)
    return c[:, 0, None] + c[:, 1, None] * x, ok, np.where(use, wmin, np.inf)


def _snap_to_edges(profiles: Profiles, pos: np.ndarray, window: np.ndarray, config: SearchConfig) -> np.ndarray:
    """Move each boundary to the strongest Gaussian-derivative edge of its sign within
    ``config.snap`` radii, where the boundary lies against the background
    (``profiles.boundary_clear``) and the sample just inside it lies in the window (the link is
    seen there, not a nearer finger); elsewhere the boundary stays where it was."""
    d, d_ok, at = gaussian_derivative(profiles.values, profiles.usable, config.sigma)
    n = profiles.shape[-1]
    clear = np.ones(pos.shape, bool) if profiles.boundary_clear is None else profiles.boundary_clear
    out = pos.copy()
    for side, inward in ((0, 1.0), (1, -1.0)):
        p = pos[..., side]
        inside = clip_index(np.rint(p + inward).astype(int), 0, n - 1)
        seen = take_last(window, inside) & clear[..., side]
        score = (config.sign if side == 0 else -config.sign) * d
        allowed = d_ok & (np.abs(at - p[..., None]) <= config.snap * profiles.radius)
        k, val, off = masked_argmax(score, allowed, config.subsample)
        found = np.isfinite(val)
        strong = found & (per_pixel(np.where(found, val, 0.0), profiles.spacing_px) >= config.min_strength)
        out[..., side] = np.where(seen & strong, at[k] + off, p)
    return out


def _valley(W: np.ndarray, curve_ok: np.ndarray, contrast: np.ndarray, S: int, config: SearchConfig
            ) -> tuple[np.ndarray, np.ndarray]:
    """The valley line's shift per profile and whether it counts: descended and refined
    (thesis §4.3.2), inside the searched shifts, and its WSSD within ``max_mismatch`` of the
    template's contrast."""
    yhat, fit_ok = _descend(W, curve_ok, S, config.max_iter)
    y, ok, wmin = _refine(W, yhat, curve_ok, S, config.subsample)
    match = np.sqrt(np.where(np.isfinite(wmin), wmin, np.inf)) <= config.max_mismatch * contrast
    return y, curve_ok & (fit_ok & ok)[:, None] & match & (np.abs(y) <= S)


def wssd_valley(profiles: Profiles, config: SearchConfig) -> Edges:
    """Boundaries from the valley line of the windowed-SSD surface against stored templates."""
    L, M, N = profiles.shape
    if profiles.templates is None or profiles.template_valid is None:
        templates, tvalid = np.zeros((L, M, N)), np.zeros(L, bool)
    else:
        templates, tvalid = profiles.templates, profiles.template_valid
    window = profiles.window & profiles.usable
    if profiles.template_mask is not None:
        window = window & profiles.template_mask
    S = profiles.max_shift(config.max_shift)
    W, counts, shifts = wssd_surface(profiles.values, profiles.usable, templates, window, S)
    enough = window.sum(-1) >= config.min_window * N
    # Contrast of the windowed template: a flat one holds no boundary to match.
    wn = np.maximum(window.sum(-1), 1)
    mean = np.where(window, templates, 0.0).sum(-1) / wn
    contrast = np.sqrt(np.where(window, (templates - mean[..., None]) ** 2, 0.0).sum(-1) / wn)
    curve_ok = tvalid[:, None] & enough & (contrast >= config.min_strength)
    y, valid = _valley(W, curve_ok, contrast, S, config)
    if config.zero_mean:   # links most of whose profiles no longer match: again, brightness offset removed
        again = valid.sum(1) * 2 < curve_ok.sum(1)
        if again.sum() * 2 > curve_ok.any(1).sum():   # most links at once: the hand's shading, not an occluder
            W[again] = wssd_surface(profiles.values[again], profiles.usable[again], templates[again], window[again],
                                    S, zero_mean=True)[0]
            y[again], valid[again] = _valley(W[again], curve_ok[again], contrast[again], S, config)
    pos = edges_about_centres(profiles.centre + y, 2 * profiles.radius)
    if config.snap > 0:
        pos = _snap_to_edges(profiles, pos, window, config)
    return Edges(pos=pos, strength=np.repeat(contrast[..., None], 2, -1), valid=np.repeat(valid[..., None], 2, -1),
                 surface=W, shifts=shifts)
