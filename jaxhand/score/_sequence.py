"""A still camera's background, learned from the sequence and from the tracked poses (the
"sequence" foreground; issue 13 item 3).

A pixel's background grey is known in one of two ways, the first preferred:

- **seen**: the mean over the frames so far where the tracked model, grown by ``margin_px``, left
  the pixel free (:meth:`SequenceBackground.observe`, after each frame);
- **anchored mode**: the most frequent grey over frames spread across the sequence, among the
  frames that can show background there: inside the hand at the first, known pose, only the
  frames that differ from the first (the hand has moved away), a grey counting more the nearer
  it lies to the background around the hand; everywhere else, every frame.

Where the first frame shows background (outside its silhouette grown by ``margin_px``), both
count only greys that agree with it: a hand that comes to rest there, a little beyond the
tracked model's outline, is neither the commonest grey nor "seen" background. A mode the
tracked model has been seen covering (the pixel matched it at least ``cover_px`` inside the model's
silhouette on ``min_covered`` frames, anywhere the first silhouette grown by ``margin_px`` lay) was a
hand part that stayed put, a fist over the fingers' first place, and is dropped. A curled fingertip
lies within a few pixels of the model's outline and may rest between the first pose's fingers, so
the test reaches that far.

On colour frames (:class:`ColourSequenceBackground`) each of the three channels learns its own
background so, and a pixel is foreground where any channel's test finds it: a hand and a wall of
the same grey still differ in colour.

A pixel known neither way (the palm that never moves) is foreground. Where that is so only because
its mode was dropped, was never seen free and the frame matches the mode again, it is
:meth:`~SequenceBackground.doubtful`: a hand part that stays put and background that a lagging
model covered (shaded like it by chance) look the same there, so the scores and the silhouette
term's outline leave it out. A pixel differs from its
background where its grey does by ``k`` noise levels, or where the mean squared difference over
its 3x3 patch exceeds ``patch_level`` squared noise levels and its own exceeds one (the patch
mask shrunk by a pixel, so it neither grows the outline nor closes a gap between fingers): a
finger whose grey lies within a few noise levels of the clutter behind it still differs over a
patch. Holes under ``fill_px`` pixels are filled: the silhouette term
reads every outline, and a hole's outline inside a finger would pull the model's onto it.
"""

from __future__ import annotations

import cv2
import numpy as np
from jaxtyping import Bool, Float

from .._errors import InputError
from ._foreground import AbstractForeground, _disc, _open, as_grey, fill_holes

__all__ = ["SequenceBackground", "ColourSequenceBackground"]

_AGREE = 3.0   # noise levels within which two greys count as the same (anchoring, covered modes)
_GUESS_GREY = 32.0   # how near (grey levels) a mode must lie to the inpainted background to count double


def _outside(mask: np.ndarray, grow_px: int) -> np.ndarray:
    """Where ``mask`` grown by ``grow_px`` leaves the image free."""
    return ~(cv2.dilate(mask.astype(np.uint8), _disc(grow_px)) > 0)


def _noise(stack: np.ndarray, hand: np.ndarray, min_noise: float) -> float:
    """The frames' noise level (grey levels): the robust spread of frame-to-frame differences
    away from the hand, over sqrt(2)."""
    away = _outside(hand, 3)
    if len(stack) < 2 or not away.any():
        return float(min_noise)
    d = np.abs(np.diff(stack[:, away], axis=0))
    return max(float(1.4826 * np.median(d) / np.sqrt(2)), min_noise)


def _anchored_mode(stack: np.ndarray, core: np.ndarray, noise: float, min_frames: int,
                   clear: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Each pixel's most frequent grey among the frames that can show background there (inside
    ``core``, those differing from the first frame; in ``clear``, where the first frame shows
    background, those agreeing with it; elsewhere all of them), refined to the mean of those near
    it; and where at least ``min_frames`` frames support it. Inside ``core`` a grey
    counts up to twice as much the nearer it lies to the background outside, inpainted across
    the hand: of a fingertip that rested where the finger started and the background seen as
    often, the background wins."""
    changed = np.abs(stack - stack[0]) > _AGREE * noise   # differs from the first frame
    candidate = np.where(core, changed, True if clear is None else ~(clear & changed))
    width = max(4.0, noise)
    n_bins = int(256 / width) + 1
    bins = np.minimum((stack / width).astype(np.intp), n_bins - 1)
    counts = np.zeros((n_bins, stack[0].size), np.uint16 if 3 * len(stack) < 2 ** 16 else np.uint32)
    pixels = np.arange(stack[0].size)
    for b, c in zip(bins.reshape(len(stack), -1), candidate.reshape(len(stack), -1)):
        np.add.at(counts, (b[c], pixels[c]), 1)
    smooth = counts.copy()   # each bin with its two neighbours (at most 3 N counts)
    smooth[1:] += counts[:-1]
    smooth[:-1] += counts[1:]
    centre = ((np.argmax(smooth, 0) + 0.5) * width).reshape(stack[0].shape)
    if core.any():
        guess = cv2.inpaint(np.clip(centre, 0, 255).astype(np.uint8), core.astype(np.uint8), 5, cv2.INPAINT_TELEA)
        levels = ((np.arange(n_bins) + 0.5) * width).astype(np.float32)
        near_guess = np.exp(-0.5 * ((levels[:, None] - guess[core][None].astype(np.float32)) / _GUESS_GREY) ** 2)
        weighted = smooth[:, core.ravel()] * (1.0 + near_guess)
        centre[core] = (np.argmax(weighted, 0) + 0.5) * width
    near = candidate & (np.abs(stack - centre) <= 2 * noise + width)
    support = near.sum(0)
    mode = np.where(support > 0, np.where(near, stack, 0).sum(0) / np.maximum(support, 1), centre)
    return mode.astype(np.float32), support >= min_frames


class SequenceBackground(AbstractForeground):
    """The background of a still camera, learned from frames spread over the sequence and, as
    tracking goes, from where the tracked model leaves the image free (see the module text).
    Mutable: :meth:`observe` adds a tracked frame.

    Attributes:
        noise: the frames' noise level (grey levels), floored at ``min_noise``.
        mode: (H, W) the anchored mode of each pixel (grey levels).
        k, patch_level, fill_px, margin_px, cover_px, open_px, min_covered: see :meth:`__init__`.
    """

    def __init__(self, frames, hand_mask, *, k: float = 4.0, patch_level: float = 3.0, fill_px: int = 100,
                 margin_px: int = 3, cover_px: int = 1, rim_px: int = 0, min_frames: int = 5, min_covered: int = 2,
                 min_noise: float = 3.0, open_px: int = 1, anchor_clear: bool = True):
        """``frames``: (N, H, W[, 3]) frames spread over the sequence, the first frame first;
        ``hand_mask``: (H, W) bool, the model's silhouette at the first frame's known pose;
        ``k``: per-pixel difference (noise levels); ``patch_level``: 3x3 mean squared difference
        (squared noise levels; 0: off); ``fill_px``: largest hole filled (px; 0: none);
        ``margin_px``: how far the tracked silhouette is grown before its outside counts as seen
        background; ``cover_px``: how far inside the tracked silhouette a pixel must lie to count
        as covered by it (``min_covered``); ``rim_px``: how far inside the first silhouette's outline the first frame
        starts to count as hand (0: from the outline; a static part's outline then follows the
        model's); ``min_frames``: frames a mode needs; ``min_covered``: frames a mode may
        match under the tracked model before it is dropped; ``anchor_clear``: where the first
        silhouette grown by ``margin_px`` leaves the first frame free, only greys agreeing with
        the first frame count as background (a hand resting beyond the tracked model's outline
        is not learned)."""
        stack = np.stack([as_grey(f, f"frames[{i}]") for i, f in enumerate(frames)]).astype(np.float32)
        if len(stack) == 0:
            raise InputError("frames: need at least one frame")
        hand = np.asarray(hand_mask, bool)
        if hand.shape != stack.shape[1:]:
            raise InputError(f"hand_mask: expected shape {stack.shape[1:]} (the frames'), got {hand.shape}")
        self.k, self.patch_level, self.fill_px = float(k), float(patch_level), int(fill_px)
        for name, value in (("margin_px", margin_px), ("cover_px", cover_px)):
            if value < 0:
                raise InputError(f"{name}: expected a whole number of pixels >= 0, got {value!r}")
        self.margin_px, self.open_px, self.min_covered = int(margin_px), int(open_px), int(min_covered)
        self.cover_px = int(cover_px)
        self.noise = _noise(stack, hand, min_noise)
        self._core = cv2.erode(hand.astype(np.uint8), _disc(rim_px)) > 0 if rim_px > 0 else hand
        self._first = stack[0]
        self._near_first = ~_outside(hand, self.margin_px)   # where a mode may be a hand part's grey
        self._clear = ~self._near_first if anchor_clear else None
        self.mode, self._mode_known = _anchored_mode(stack, self._core, self.noise, min_frames, self._clear)
        self._seen_sum = np.zeros(hand.shape, np.float64)
        self._seen = np.zeros(hand.shape, np.int32)
        self._covered = np.zeros(hand.shape, np.int32)

    def observe(self, image, silhouette: Bool[np.ndarray, "H W"]) -> None:
        """Learn from a tracked frame: ``silhouette`` is the model's mask at the frame's estimate."""
        grey = self._grey(image).astype(np.float32)
        sil = np.asarray(silhouette, bool)
        if sil.shape != grey.shape:
            raise InputError(f"silhouette: expected shape {grey.shape} (the frames'), got {sil.shape}")
        free = _outside(sil, self.margin_px)
        if self._clear is not None:
            free &= ~self._clear | (np.abs(grey - self._first) <= _AGREE * self.noise)
        self._seen_sum += np.where(free, grey, 0.0)
        self._seen += free
        inside = cv2.erode(sil.astype(np.uint8), _disc(self.cover_px)) > 0
        self._covered += inside & self._near_first & (np.abs(grey - self.mode) <= _AGREE * self.noise)

    def background(self) -> tuple[Float[np.ndarray, "H W"], Bool[np.ndarray, "H W"]]:
        """The background greys so far and where they are known."""
        seen = self._seen > 0
        background = np.where(seen, self._seen_sum / np.maximum(self._seen, 1), self.mode).astype(np.float32)
        return background, seen | (self._mode_known & (self._covered < self.min_covered))

    def mask(self, image) -> np.ndarray:
        grey = self._grey(image).astype(np.float32)
        background, known = self.background()
        z2 = ((grey - background) / self.noise) ** 2
        differs = z2 > self.k ** 2
        if self.patch_level > 0:
            patch = (cv2.boxFilter(z2, -1, (3, 3)) > self.patch_level).astype(np.uint8)
            differs |= (cv2.erode(patch, _disc(1)) > 0) & (z2 > 1.0)   # a gap between fingers stays open
        return _open(fill_holes(differs | ~known, self.fill_px), self.open_px)

    def doubtful(self, image, mask=None) -> np.ndarray:
        """Foreground pixels that match a dropped mode and were never seen free: a hand part
        resting there or the background, shaded like it by chance, look alike. ``mask``: the
        frame's :meth:`mask`, where the caller has it."""
        grey = self._grey(image).astype(np.float32)
        dropped = self._mode_known & (self._covered >= self.min_covered) & (self._seen == 0)
        mask = self.mask(image) if mask is None else np.asarray(mask, bool)
        return dropped & (np.abs(grey - self.mode) <= self.k * self.noise) & mask

    def _grey(self, image) -> np.ndarray:
        grey = as_grey(image)
        if grey.shape != self.mode.shape:
            raise InputError(f"image: expected shape {self.mode.shape} (the background's), got {grey.shape}")
        return grey


class ColourSequenceBackground(AbstractForeground):
    """:class:`SequenceBackground` for colour frames: one per channel (B, G, R), each learning
    from that channel alone; a pixel is foreground where any channel's mask holds it.

    Attributes:
        channels: the three channels' :class:`SequenceBackground` (B, G, R).
    """

    def __init__(self, frames, hand_mask, **options):
        """``frames``: (N, H, W, 3) BGR frames spread over the sequence, the first frame first;
        ``hand_mask`` and ``options``: as for :class:`SequenceBackground`, shared by the channels."""
        planes = [_bgr_planes(f, f"frames[{i}]") for i, f in enumerate(frames)]
        self.channels = tuple(SequenceBackground([p[c] for p in planes], hand_mask, **options) for c in range(3))

    def observe(self, image, silhouette: Bool[np.ndarray, "H W"]) -> None:
        """Learn from a tracked frame (see :meth:`SequenceBackground.observe`)."""
        for channel, plane in zip(self.channels, _bgr_planes(image)):
            channel.observe(plane, silhouette)

    def mask(self, image) -> np.ndarray:
        return np.logical_or.reduce([c.mask(p) for c, p in zip(self.channels, _bgr_planes(image))])

    def doubtful(self, image, mask=None) -> np.ndarray:
        """Foreground pixels that every channel calling them foreground doubts (``mask`` is not
        needed: each channel's own is)."""
        planes = _bgr_planes(image)
        calls = [(c.mask(p), c.doubtful(p)) for c, p in zip(self.channels, planes)]
        return np.logical_or.reduce([m for m, _ in calls]) & np.logical_and.reduce([d | ~m for m, d in calls])


def _bgr_planes(image, where: str = "image") -> tuple[np.ndarray, ...]:
    """A BGR frame's three channels, each as its own grey image."""
    a = np.asarray(image)
    if a.ndim != 3 or a.shape[2] != 3:
        raise InputError(f"{where}: expected a BGR frame (H, W, 3), got shape {a.shape}; grey frames take "
                         "SequenceBackground")
    return tuple(np.ascontiguousarray(a[..., c]) for c in range(3))
