"""The silhouette as residuals of the solve: the whole model against the whole foreground.

The edge features constrain where a link's sides are but hardly how long it looks, so a finger
that flexes towards or away from the camera drifts while its edge residuals stay small. This
term compares the model's silhouette (every pill, occluders included) with the frame's
foreground in both directions, as a chamfer of signed distances (no visibility reasoning is
needed: the silhouette of a union is the union of the silhouettes):

- **covered**: each point of the foreground's outline should lie on the model's outline:
  ``r = rho(min_i d_i(x))`` with ``d_i`` the signed distance (px) from the image point ``x`` to
  pill ``i``'s image (a smooth minimum over pills);
- **inside**: each point on the outline of each pill's image should lie inside the foreground:
  ``r = rho(max(0, D(p)))`` with ``D`` the foreground's signed distance map (px, positive
  outside), read bilinearly.

``rho(d) = d / (1 + (d/s)^2)^(1/4)`` (a pseudo-Huber residual: its square grows like ``|d| s``
far out, so a few wrong foreground pixels cannot dominate). A pill's image is taken as the
tapered 2-D pill between the images of its end spheres (their radii from the camera's local
scale at each end): exact for orthographic cameras, within a small fraction of a pixel for a
finger some hundreds of millimetres from a pinhole camera.

The host part (:func:`silhouette_term`) builds a frame's numbers once per camera (the distance
map and outline samples, fixed shapes, so one compiled program serves every frame); the traced
part (:class:`SilhouettePrior`) is a pose prior in the sense of :mod:`jaxhand.priors`.
"""

from __future__ import annotations

import dataclasses

import cv2
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.ndimage import map_coordinates
from jaxtyping import Array, ArrayLike, Bool, Float

from .._errors import InputError
from ..kinematics import all_pills, pixel_scale, pose
from ..model import Model
from ..priors import AbstractTerm
from ._foreground import AbstractForeground, as_grey

__all__ = ["SilhouetteTermConfig", "SilhouetteTerm", "SilhouettePrior", "silhouette_term", "pill_images", "roi_box"]


@dataclasses.dataclass(frozen=True)
class SilhouetteTermConfig:
    """The silhouette term of the solve (``ImageConfig.silhouette_term``; host values).

    Attributes:
        weight: square-root weight of each residual (a residual of 1 px counts as ``weight`` px
            of edge residual); 0 turns the term off.
        scale_px: the pseudo-Huber scale ``s`` (px): distances beyond it count less than
            quadratically.
        contour_points: how many points of the foreground's outline are compared (spread evenly
            along it; a fixed number, so the compiled solve is reused).
        outline_fractions: where along each pill its two sides are sampled (0: start, 1: end);
            the two end caps are always sampled.
        min_share, max_share: the term is skipped on a frame whose foreground covers less or more
            than this share of the image (nothing to compare, or the foreground model failed, as
            a threshold does on a bright, cluttered background).
        merit_rms_px: the hypotheses weigh a candidate by ``1 / (1 + (e / merit_rms_px)^2)`` of
            its robust RMS silhouette distance ``e`` (px), besides its edge residuals.
        edge_weight: square-root weight of the **edge** residuals: each visible point on the
            sides of each link's image (and on the end of each tip) should lie on an image edge
            (Canny), ``r = rho(E(p))`` with ``E`` the distance (px) to the nearest edge pixel.
            This sees the fingers in front of the palm, where the silhouette cannot. 0: off.
        edge_fractions: where along each link its two sides are compared with the edges.
        canny_low, canny_high: Canny's hysteresis thresholds (grey levels of the gradient)
            after a Gaussian blur of ``canny_sigma_px``.
        roi_margin: the foreground's outline is compared only inside the box of the model's
            silhouette at the frame's starting pose, grown on every side by this fraction of the
            box's larger side (at least ``roi_min_px``): foreground far from the hand (a body, a
            second object, a forearm leaving the image) is not the model's to cover. None: the
            whole image.
        roi_min_px: the least margin of that box (px).
        cover_gate_px: beyond about this distance (px) outside every pill, a point of the
            foreground's outline pulls less the farther it lies, and hardly at all far out: a
            forearm, a sleeve or a second object is not the model's to cover. None: every point
            pulls alike however far (the pseudo-Huber residual alone).
        rim_px: how far (px) the foreground falls short of the hand's outline (negative: reaches
            beyond it); the pills are compared with it as if that much thinner (fatter). A mask
            from a segmentation network, eroded or grown by a pixel, otherwise pulls every finger
            in depth to match its width. "auto": measured once per camera at the first frame's
            pose (:meth:`SilhouettePrior.outline_bias_px`), which must then be right. 0: as they are.
    """

    weight: float = 0.0
    scale_px: float = 5.0
    contour_points: int = 128
    outline_fractions: tuple[float, ...] = (0.0, 0.25, 0.5, 0.75, 1.0)
    min_share: float = 0.002
    max_share: float = 0.6
    merit_rms_px: float = 2.0
    edge_weight: float = 0.0
    edge_fractions: tuple[float, ...] = (0.2, 0.4, 0.6, 0.8)
    canny_low: float = 20.0
    canny_high: float = 50.0
    canny_sigma_px: float = 1.0
    roi_margin: float | None = 0.25
    roi_min_px: float = 20.0
    cover_gate_px: float | None = None
    rim_px: float | str = 0.0

    def __post_init__(self):
        def need(cond, field, msg):
            if not cond:
                raise InputError(f"silhouette_term.{field}: {msg}")

        need(self.weight >= 0, "weight", f"need >= 0 (0: off), got {self.weight!r}")
        need(self.scale_px > 0, "scale_px", f"need > 0 px, got {self.scale_px!r}")
        need(isinstance(self.contour_points, int) and self.contour_points >= 8, "contour_points",
             f"need an int >= 8, got {self.contour_points!r}")
        need(len(self.outline_fractions) >= 1 and all(0 <= f <= 1 for f in self.outline_fractions),
             "outline_fractions", f"need fractions in [0, 1], got {self.outline_fractions!r}")
        need(0 <= self.min_share < self.max_share <= 1, "min_share/max_share",
             f"need 0 <= min_share < max_share <= 1, got {self.min_share!r}, {self.max_share!r}")
        need(self.merit_rms_px > 0, "merit_rms_px", f"need > 0 px, got {self.merit_rms_px!r}")
        need(self.edge_weight >= 0, "edge_weight", f"need >= 0 (0: off), got {self.edge_weight!r}")
        need(len(self.edge_fractions) >= 1 and all(0 < f < 1 for f in self.edge_fractions), "edge_fractions",
             f"need fractions in (0, 1), got {self.edge_fractions!r}")
        need(0 <= self.canny_low <= self.canny_high, "canny_low/canny_high",
             f"need 0 <= low <= high, got {self.canny_low!r}, {self.canny_high!r}")
        need(self.canny_sigma_px >= 0, "canny_sigma_px", f"need >= 0 px, got {self.canny_sigma_px!r}")
        need(self.roi_margin is None or self.roi_margin >= 0, "roi_margin",
             f"need a fraction >= 0 or None (the whole image), got {self.roi_margin!r}")
        need(self.roi_min_px >= 0, "roi_min_px", f"need >= 0 px, got {self.roi_min_px!r}")
        need(self.cover_gate_px is None or self.cover_gate_px > 0, "cover_gate_px",
             f"need > 0 px or None (off), got {self.cover_gate_px!r}")
        need(self.rim_px == "auto" or (isinstance(self.rim_px, (int, float)) and np.isfinite(self.rim_px)), "rim_px",
             f"need a number of px (0: off) or 'auto' (measured at the first frame's pose), got {self.rim_px!r}")

    @property
    def enabled(self) -> bool:
        return self.weight > 0 or self.edge_weight > 0


def _rho(d, scale):
    return d / (1.0 + (d / scale) ** 2) ** 0.25


def _pill_geometry(model: Model, camera, q) -> tuple[Array, ...]:
    pills = all_pills(model, pose(model, q))
    a, za = camera.project(pills.start)
    b, zb = camera.project(pills.end)

    return (a, b, pills.radius_mm * pixel_scale(camera, pills.start), pills.radius_mm * pixel_scale(camera, pills.end),
            za, zb)


def pill_images(model: Model, camera, q: Float[ArrayLike, " nq"]) -> tuple[Array, Array, Array, Array]:
    """Every pill's image (links, then occluders): start and end pixels (pills, 2) and the
    radii (px) of its end spheres there (pills,), from the camera's local scale at each end."""
    return _pill_geometry(model, camera, q)[:4]


def visible_outline(model: Model, geometry: tuple, fractions) -> tuple[Array, Array]:
    """Points on the sides of every link's image at ``fractions``, then on the end of every
    tip, and which of them no nearer pill covers (a point whose pixel lies more than half a
    pixel inside another pill whose axis is nearer there by over 2 mm; the mask carries no
    derivative)."""
    a, b, ra, rb, za, zb = geometry
    n_links = model.n_links
    bl, rbl = b[:n_links], rb[:n_links]
    u, normal, centre, r = _sides(a[:n_links], bl, ra[:n_links], rbl, fractions)
    f = jnp.asarray(fractions, a.dtype)
    tips = np.array(model.tip_links, dtype=int)
    pts = jnp.concatenate([(centre + r * normal[:, None]).reshape(-1, 2), (centre - r * normal[:, None]).reshape(-1, 2),
                           bl[tips] + rbl[tips, None] * u[tips]])
    own = np.concatenate([np.repeat(np.arange(n_links), len(fractions))] * 2 + [tips])
    depth = jnp.concatenate([(za[:n_links, None] + f[None] * (zb - za)[:n_links, None]).reshape(-1)] * 2
                            + [zb[tips]])
    g = jax.lax.stop_gradient((pts, a, b, ra, rb, za, zb, depth))
    p, a, b, ra, rb, za, zb, depth = g
    ab = b - a
    t = jnp.clip(jnp.sum((p[:, None] - a[None]) * ab[None], -1) / (jnp.sum(ab * ab, -1)[None] + 1e-9), 0.0, 1.0)
    inside = pill_distances(p, a, b, ra, rb) < -0.5
    nearer = za[None] + t * (zb - za)[None] < depth[:, None] - 2.0
    others = np.arange(a.shape[0])[None] != own[:, None]
    return pts, ~jnp.any(inside & nearer & others, axis=1)


def _pill_distance(p, a, b, ra, rb):
    """Signed distance (px, negative inside) from the point ``p`` (2,) to one tapered 2-D pill."""
    ab = b - a
    t = jnp.clip(jnp.dot(p - a, ab) / (jnp.dot(ab, ab) + 1e-9), 0.0, 1.0)   # Guard: a pill seen end-on
    e = p - (a + t * ab)
    return jnp.sqrt(jnp.dot(e, e) + 1e-9) - (ra + t * (rb - ra))           # Guard: sqrt'(0)


# every point against every pill, and its gradient in the pill's numbers
_all_pairs = jax.vmap(jax.vmap(_pill_distance, (None, 0, 0, 0, 0)), (0, None, None, None, None))
_all_grads = jax.vmap(jax.vmap(jax.grad(_pill_distance, argnums=(1, 2, 3, 4)), (None, 0, 0, 0, 0)),
                      (0, None, None, None, None))


def pill_distances(points, a, b, ra, rb) -> Float[Array, "n pills"]:
    """Signed distance (px, negative inside) from each point (n, 2) to each tapered 2-D pill."""
    return _all_pairs(points, a, b, ra, rb)


@jax.custom_jvp
def nearest_pill_distance(points, a, b, ra, rb) -> Float[Array, " n"]:
    """A smooth minimum (1 px) over pills of :func:`pill_distances`: each point's signed distance
    to the union of the pills. Its derivative is formed once per point and pill and then applied
    to every tangent, so ``jax.jacfwd`` over many pose entries costs little more than one."""
    return -jax.scipy.special.logsumexp(-pill_distances(points, a, b, ra, rb), axis=1)


@nearest_pill_distance.defjvp
def _nearest_jvp(primals, tangents):
    points, a, b, ra, rb = primals
    _, da, db, dra, drb = tangents
    d = pill_distances(points, a, b, ra, rb)
    share = jax.nn.softmax(-d, axis=1)                       # d(smooth min) / d d_ij
    ga, gb, gra, grb = _all_grads(points, a, b, ra, rb)      # (n, pills, 2), (n, pills, 2), (n, pills), (n, pills)
    dd = (jnp.einsum("npk,pk->np", ga, da) + jnp.einsum("npk,pk->np", gb, db) + gra * dra[None] + grb * drb[None])
    return -jax.scipy.special.logsumexp(-d, axis=1), jnp.sum(share * dd, axis=1)


def _sides(a, b, ra, rb, fractions) -> tuple[Array, Array, Array, Array]:
    """Each pill's unit axis and normal in the image, and the axis points and radii at ``fractions``."""
    u = b - a
    u = u / jnp.sqrt(jnp.sum(u * u, -1) + 1e-9)[:, None]
    f = jnp.asarray(fractions, a.dtype)
    centre = a[:, None] + f[None, :, None] * (b - a)[:, None]
    r = (ra[:, None] + f[None] * (rb - ra)[:, None])[..., None]
    return u, jnp.stack([-u[:, 1], u[:, 0]], -1), centre, r


def pill_outlines(a, b, ra, rb, fractions) -> Float[Array, "m 2"]:
    """Points on each pill's image outline: both sides at ``fractions`` and both cap ends."""
    u, n, centre, r = _sides(a, b, ra, rb, fractions)
    pts = jnp.concatenate([centre + r * n[:, None], centre - r * n[:, None], (a - ra[:, None] * u)[:, None],
                           (b + rb[:, None] * u)[:, None]], 1)
    return pts.reshape(-1, 2)


class SilhouettePrior(eqx.Module):
    """A frame's silhouette term bound to a model and camera: ``prior(q) -> residuals`` (px times
    the weight): the covered residuals of the outline points, then the inside residuals of the
    pills' outline points."""

    model: Model
    camera: eqx.Module
    term: SilhouetteTerm

    def distances(self, q) -> tuple[tuple[Array, Array, Array], ...]:
        """The unweighted distances (px), their masks and weights, block by block: outline to
        model, model to foreground, and (when on) visible link sides to the nearest image edge."""
        t = self.term
        geometry = _pill_geometry(self.model, self.camera, q)
        a, b, ra, rb = geometry[:4]
        ra, rb = ra - jnp.minimum(t.rim_px, 0.5 * ra), rb - jnp.minimum(t.rim_px, 0.5 * rb)   # thinner by the rim
        height, width = t.sdf.shape

        def in_image(p):
            return (p[:, 0] >= 0) & (p[:, 0] <= width - 1) & (p[:, 1] >= 0) & (p[:, 1] <= height - 1)

        def read(grid, p):
            return map_coordinates(grid, [p[:, 1], p[:, 0]], order=1, mode="nearest")

        covered = nearest_pill_distance(t.contour, a, b, ra, rb)
        covered = covered / jnp.sqrt(1.0 + (jax.nn.relu(covered) * t.cover_gate_inv) ** 2)   # far outside: pulls less
        pts = pill_outlines(a, b, ra, rb, t.fractions)
        blocks = [(covered, t.contour_valid, t.weight),
                  (jax.nn.relu(read(t.sdf, pts)), in_image(pts) & t.active, t.weight)]
        if t.edges is not None:
            pts, visible = visible_outline(self.model, geometry, t.edge_fractions)
            blocks.append((read(t.edges, pts), visible & in_image(pts), t.edge_weight))
        return tuple(blocks)

    def __call__(self, q: Float[ArrayLike, " nq"]) -> Float[Array, " r"]:
        s = self.term.scale_px
        return jnp.concatenate([w * jnp.where(ok, _rho(d, s), 0.0) for d, ok, w in self.distances(q)])

    def rms_px(self, q) -> Float[Array, ""]:
        """The robust RMS distance (px) of the valid residuals (0 when there are none)."""
        blocks = self.distances(q)
        s = self.term.scale_px
        blocks = [(d, ok & (w > 0)) for d, ok, w in blocks]   # only the blocks that are on
        total = sum(jnp.sum(jnp.where(ok, _rho(d, s) ** 2, 0.0)) for d, ok in blocks)
        count = sum(jnp.sum(ok) for _, ok in blocks).astype(total.dtype)
        return jnp.sqrt(total / jnp.maximum(count, 1.0))   # Guard: an inactive term gives 0, not NaN

    def outline_bias_px(self, q, reach_px: float = 3.0) -> float:
        """The median signed distance (px) from the foreground's outline to the model's at ``q``
        (pills as they are, whatever the term's ``rim_px``) over the outline points within
        ``reach_px`` of it: about minus the foreground's shortfall at the hand's outline when ``q``
        is right (0 with no such point)."""
        unthinned = SilhouettePrior(self.model, self.camera, eqx.tree_at(lambda t: t.rim_px, self.term,
                                                                          jnp.zeros_like(self.term.rim_px)))
        d, ok, _ = unthinned.distances(q)[0]
        d = np.asarray(d)[np.asarray(ok) & np.asarray(self.term.active)]
        d = d[np.abs(d) <= reach_px]
        return float(np.median(d)) if len(d) else 0.0


class SilhouetteTerm(AbstractTerm):
    """One camera's foreground for one frame, unbound (arrays only, fixed shapes).

    Attributes:
        camera: which camera of the rig (static).
        fractions: :attr:`SilhouetteTermConfig.outline_fractions` (static).
        sdf: (H, W) signed distance to the foreground's outline (px, positive outside).
        contour: (N, 2) points (x, y) on the foreground's outline.
        contour_valid: (N,) which of them are real (the rest pad to N).
        active: whether the frame's foreground was usable (else the term is all zeros).
        weight, scale_px, merit_rms_px, edge_weight: :class:`SilhouetteTermConfig`'s numbers (traced).
        cover_gate_inv: 1 / :attr:`SilhouetteTermConfig.cover_gate_px` (0: off; traced).
        rim_px: :attr:`SilhouetteTermConfig.rim_px` (traced).
        edges: (H, W) distance (px) to the nearest Canny edge pixel, or None (edges off).
        edge_fractions: :attr:`SilhouetteTermConfig.edge_fractions` (static).
    """

    judged = True
    camera: int = eqx.field(static=True)
    fractions: tuple[float, ...] = eqx.field(static=True)
    sdf: Float[Array, "H W"]
    contour: Float[Array, "n 2"]
    contour_valid: Bool[Array, " n"]
    active: Bool[Array, ""]
    weight: Float[Array, ""]
    scale_px: Float[Array, ""]
    merit_rms_px: Float[Array, ""]
    edge_weight: Float[Array, ""]
    cover_gate_inv: Float[Array, ""]
    rim_px: Float[Array, ""]
    edges: Float[Array, "H W"] | None = None
    edge_fractions: tuple[float, ...] = eqx.field(static=True, default=())

    def bind(self, model: Model, rig: tuple) -> SilhouettePrior:
        return SilhouettePrior(model=model, camera=rig[self.camera], term=self)

    def merit(self, model: Model, rig: tuple, q) -> Float[Array, ""]:
        e = self.bind(model, rig).rms_px(q)
        return 1.0 / (1.0 + (e / self.merit_rms_px) ** 2)


def roi_box(silhouette: Bool[np.ndarray, "H W"], margin: float | None, min_px: float
            ) -> tuple[float, float, float, float] | None:
    """(x0, y0, x1, y1): the box of ``silhouette`` grown on every side by ``margin`` times its
    larger side, at least ``min_px`` (None: no box, for margin None or an empty silhouette)."""
    if margin is None or not silhouette.any():
        return None
    x, y, w, h = cv2.boundingRect(silhouette.astype(np.uint8))
    grow = max(margin * max(w, h), min_px)
    return x - grow, y - grow, x + w - 1 + grow, y + h - 1 + grow


def _outline_points(mask: np.ndarray, n: int, box=None) -> tuple[np.ndarray, np.ndarray]:
    """``n`` points spread evenly along the mask's outlines (holes included), leaving out the
    image's border rows and columns (a forearm leaving the image is not an outline) and, with a
    ``box`` (x0, y0, x1, y1), whatever lies outside it."""
    contours, _ = cv2.findContours(mask, cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
    pts = np.concatenate([c.reshape(-1, 2) for c in contours]).astype(float) if contours else np.zeros((0, 2))
    h, w = mask.shape
    x0, y0, x1, y1 = (0, 0, w - 1, h - 1) if box is None else (max(box[0], 0), max(box[1], 0), min(box[2], w - 1),
                                                               min(box[3], h - 1))
    pts = pts[(pts[:, 0] > 0) & (pts[:, 0] < w - 1) & (pts[:, 1] > 0) & (pts[:, 1] < h - 1)
              & (pts[:, 0] >= x0) & (pts[:, 0] <= x1) & (pts[:, 1] >= y0) & (pts[:, 1] <= y1)]
    out, valid = np.zeros((n, 2)), np.zeros(n, bool)
    if len(pts):
        take = np.unique(np.linspace(0, len(pts) - 1, min(n, len(pts))).round().astype(int))
        out[: len(take)], valid[: len(take)] = pts[take], True
    return out, valid


def _rim(config: SilhouetteTermConfig, rim_px: float | None) -> float:
    if rim_px is not None:
        return float(rim_px)
    return 0.0 if config.rim_px == "auto" else float(config.rim_px)


def silhouette_term(image, foreground: AbstractForeground, camera: int, config: SilhouetteTermConfig,
                    dtype=None, box=None, rim_px: float | None = None) -> SilhouetteTerm:
    """A frame's :class:`SilhouetteTerm` for camera ``camera`` of the rig from its image and
    foreground model (inactive when the foreground covers less than ``config.min_share`` or
    more than ``config.max_share`` of the image); ``box`` (x0, y0, x1, y1; :func:`roi_box`)
    limits the foreground's outline points to a region of interest; ``rim_px`` replaces
    ``config.rim_px`` (needed where that is "auto", which counts as 0 without it)."""
    mask = foreground.mask(image).astype(np.uint8)
    share = float(mask.mean())
    active = config.min_share <= share <= config.max_share
    if active:
        outside = cv2.distanceTransform(1 - mask, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        inside = cv2.distanceTransform(mask, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        # the outline lies half a pixel beyond the last foreground pixel centre
        sdf = np.where(mask > 0, 0.5 - inside, outside - 0.5)
        contour, valid = _outline_points(mask * 255, config.contour_points, box)
        rows, cols = contour[:, 1].astype(int), contour[:, 0].astype(int)
        doubtful = foreground.doubtful(image, mask > 0)
        if doubtful.any():   # an outline through pixels the foreground cannot call pulls nothing
            valid &= ~(cv2.dilate(doubtful.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0)[rows, cols]
        gy, gx = np.gradient(sdf)   # half a pixel outwards, onto the outline itself
        g = np.stack([gx[rows, cols], gy[rows, cols]], -1)
        contour = contour + 0.5 * g / np.maximum(np.linalg.norm(g, axis=-1, keepdims=True), 1e-9)
    else:
        n = config.contour_points
        sdf, contour, valid = np.zeros(mask.shape), np.zeros((n, 2)), np.zeros(n, bool)
    dtype = jnp.asarray(0.0).dtype if dtype is None else dtype
    edges = None
    if config.edge_weight > 0:
        grey = as_grey(image)
        if config.canny_sigma_px > 0:
            grey = cv2.GaussianBlur(grey, (0, 0), config.canny_sigma_px)
        found = cv2.Canny(grey, config.canny_low, config.canny_high, L2gradient=True)
        edges = jnp.asarray(cv2.distanceTransform(np.where(found > 0, 0, 255).astype(np.uint8), cv2.DIST_L2,
                                                  cv2.DIST_MASK_PRECISE), dtype)
    return SilhouetteTerm(camera=camera, fractions=tuple(float(f) for f in config.outline_fractions),
                          sdf=jnp.asarray(sdf, dtype), contour=jnp.asarray(contour, dtype),
                          contour_valid=jnp.asarray(valid), active=jnp.asarray(active),
                          weight=jnp.asarray(config.weight, dtype), scale_px=jnp.asarray(config.scale_px, dtype),
                          merit_rms_px=jnp.asarray(config.merit_rms_px, dtype),
                          edge_weight=jnp.asarray(config.edge_weight, dtype),
                          cover_gate_inv=jnp.asarray(1.0 / (config.cover_gate_px or np.inf), dtype),
                          rim_px=jnp.asarray(_rim(config, rim_px), dtype), edges=edges,
                          edge_fractions=tuple(float(f) for f in config.edge_fractions))
