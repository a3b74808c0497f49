"""Register a suspect mesh to the marked mesh's frame before reading a robust watermark.

The key stores a reference frame of the MARKED surface: seeded surface samples (3,000) with their
normals, plus the centroid, PCA axes and scale of the surface (area-weighted, so that re-meshing,
simplification or subdivision do not move them). ``register`` maps a suspect into that frame:

1. Initial guesses: the identity (most copies are not rotated; PCA is useless on a copy cropped to
   half), and the PCA alignment (centroid, axes, scale from the eigenvalues) with the 8 sign flips of
   the axes: 4 rotations and 4 mirror images (mirroring a model is one click in any 3D tool). Two axes
   of about equal spread (a round or square section: a flange, a shaft) leave the turn about the third
   undetermined, and on a round part with small features ICP hardly turns from where it starts: there
   the best turns come from the circular cross-correlation of how the surface lies around that axis in
   the suspect and in the reference (``_angular_starts``, both handedness cases, the axis either way).
2. Each guess is refined by trimmed similarity ICP, point-to-plane against the reference normals
   (sampling offsets along the surface then cost nothing, unlike point-to-point): the closest
   ``TRIM`` share of pairs drive a linearised least-squares step (scale, rotation, translation).
   Suspect samples are the sources and the reference points the targets, so a cropped suspect still
   finds a counterpart for all its points. The step keeps the handedness of its start.
3. The residual is the trimmed point-to-point RMS (point-to-point, so that a fit sliding along a flat
   part cannot look perfect; a guess whose scale collapsed or exploded is dropped). A (nearly)
   symmetric shape has several poses of the same residual, of which only one carries the mark where
   the key expects it: so the registration does not choose. ``register_poses`` gives every distinct
   pose whose residual is within ``POSE_RATIO`` of the best (at most ``POSES``), and the reader keeps
   the one where its mark reads strongest, paying for the poses in its p-value. The identity comes
   first, alone, when its residual is already at the sampling noise (two samplings of the same
   surface, stored in the key as ``floor``): a reader that finds its mark there tries nothing else.
   Accuracy is ~0.1 % of the size: enough for the robust reading, which is relative to a ring around
   each site.
4. A copy cut by a plane AND moved defeats both starts: its PCA is not the reference's. When no start
   reaches twice the sampling noise, the reference samples are cut by ``CUT_DIRECTIONS`` planes at
   ``CUT_KEEP`` shares each; the cuts whose PCA shape (eigenvalue ratios) is closest to the suspect's
   give ``CUT_CANDIDATES`` x 8 more starts, screened by ICP on every ``SCREEN_STEP``-th suspect
   sample against a third of the reference ones. The best ``CUT_FINALISTS`` and the best plain starts
   are refined in full (30 iterations).
   A finalist whose residual is still ``ABANDON_RATIO`` times the best plausible one's after
   ``ABANDON_AFTER`` iterations (typically the plain start, sliding slowly in a wrong pose) is
   dropped there.

Nearest neighbours come from one KD-tree over the key's samples (``pmwm.spatial.PointIndex``), built
once per registration; the starts of each step are refined together, one tree query per ICP iteration
for all of them, and their least-squares steps are solved together (``_lstsq``). In the final
refinement, where the poses converge, a point is searched again only when its nearest sample can have
changed (``pmwm.spatial.MovingNearest``: the same answers).
"""

from __future__ import annotations

from dataclasses import dataclass
import itertools
from typing import Iterator

import numpy as np

from .base import Progress, no_progress
from .sampling import sample_surface
from .spatial import MovingNearest, PointIndex, nearest


TRIM = 0.65  # share of the closest pairs used by ICP (robust to cropping to half)
ICP_ITERATIONS = 30
COARSE_ITERATIONS = 8
COARSE_STEP = 4  # the PCA starts' coarse fits use every 4th suspect sample (they only rank the starts)
SUSPECT_SAMPLES = 1500
CUT_DIRECTIONS = 128  # plane directions tried for cropped-and-moved copies (Fibonacci sphere)
CUT_KEEP = (0.5, 0.6, 0.7, 0.8, 0.9)  # shares of the reference kept by each cut
CUT_CANDIDATES = 16  # cuts whose PCA shape is closest to the suspect's
CUT_FINALISTS = 4  # screened cut starts refined in full
SCREEN_STEP = 6  # the cut starts are screened on every 6th suspect sample (and every 3rd reference one)
# a finalist whose trimmed residual is still this many times the best one's after that many
# iterations is abandoned (a wrong pose sliding slowly along the surface)
ABANDON_RATIO, ABANDON_AFTER = 1.8, 5
# sign flips of the PCA axes: the 4 proper ones (rotations), then the 4 that mirror
SIGNS = ((1, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1), (-1, -1, -1), (-1, 1, 1), (1, -1, 1), (1, 1, -1))
POSES = 32  # the most poses a reader tries (it pays for them in its p-value): a round part's eighths of a turn
POSE_RATIO = 1.5  # a refined pose whose residual is within this factor of the best one's is plausible
COARSE_RATIO = 1.4  # the coarse fits within this factor of the best one's are refined
EQUAL_SPREAD = 1.15  # two PCA axes whose spreads differ by less than this factor: turns about the third are searched
ANGLE_SAMPLES = 6000  # suspect samples of the angular signature (the key's 3,000 are the reference's)
ANGLE_BINS = 256  # bins of the angle about the axis
RING_BINS, HEIGHT_BINS = 8, 8  # bins of the distance from the axis and of the height along it
ANGLE_BLUR = 2.0  # degrees: the signatures' angular blur (a slightly tilted axis, sampling noise)
ANGLE_PEAKS = 8  # the most turns about an axis of equal spreads tried as starts, per handedness case
ANGLE_SHARE = 0.6  # ... those whose correlation reaches this share of the best one of all four cases
ANGLE_APART = 12.0  # degrees: two turns of one case closer than this are one peak
DISTINCT = 0.05  # two poses differ when they place the suspect's PCA frame this far apart (/ reference scale)


@dataclass
class RegistrationInfo:
    """How the suspect was aligned: x_ref = scale * R @ x + t."""

    rotation: np.ndarray
    scale: float
    translation: np.ndarray
    residual: float  # trimmed RMS point-to-point residual / reference scale
    init: str  # "identity", "pca<signs>" or "cut<j><signs>"
    mirrored: bool = False  # the suspect is a mirror image of the reference (det R < 0)


@dataclass
class SurfaceFrame:
    """A reference surface for registration, as the key stores it.

    points, normals : (k, 3) float64 surface samples (rounded to 9 and 6 decimals, as stored) and
    their smooth unit normals; centroid (3,), axes (3, 3) (rows) and scale of their PCA; floor: the
    trimmed RMS nearest-sample distance between two samplings of the same surface, / scale.
    """

    points: np.ndarray
    normals: np.ndarray
    centroid: np.ndarray
    axes: np.ndarray
    scale: float
    floor: float = 0.0

    def to_json(self) -> dict:
        return {
            "points": self.points.tolist(),
            "normals": self.normals.tolist(),
            "centroid": self.centroid.tolist(),
            "axes": self.axes.tolist(),
            "scale": self.scale,
            "floor": self.floor,
        }

    @classmethod
    def from_json(cls, d: dict) -> "SurfaceFrame":
        """The frame from its JSON form; ValueError, KeyError or TypeError when it is not one."""
        shapes = {"points": (-1, 3), "normals": (-1, 3), "centroid": (3,), "axes": (3, 3)}
        arrays = {k: np.asarray(d[k], np.float64).reshape(shp) for k, shp in shapes.items()}
        frame = cls(**arrays, scale=float(d["scale"]), floor=float(d.get("floor", 0.0)))
        if (
            not all(np.all(np.isfinite(v)) for v in (*arrays.values(), frame.scale, frame.floor))
            or frame.scale <= 0
            or len(frame.points) != len(frame.normals)
            or len(frame.points) < 3
        ):
            raise ValueError("registration frame")
        return frame


def surface_frame(vertices: np.ndarray, faces: np.ndarray, n_samples: int, seed: int) -> SurfaceFrame:
    """The reference frame of a surface: ``n_samples`` area-uniform samples and their PCA."""
    P, N = sample_surface(vertices, faces, n_samples, seed, normals=True)
    centroid, axes, scale = _pca(P)
    return SurfaceFrame(
        points=np.round(P, 9),
        normals=np.round(N, 6),
        centroid=centroid,
        axes=axes,
        scale=scale,
        floor=_self_floor(P, vertices, faces, seed) / scale,
    )


def register(
    suspect_V: np.ndarray, suspect_F: np.ndarray, frame: SurfaceFrame, seed: int = 0, progress: Progress = None
) -> tuple[np.ndarray, RegistrationInfo]:
    """The suspect's vertices mapped into the reference frame by the pose of smallest residual, and how
    (``register_poses``' best; ``progress(fraction, message)`` at its stages). suspect_V : (n, 3) float64,
    suspect_F : (m, 3) int64; returns (n, 3) float64."""
    poses = list(register_poses(suspect_V, suspect_F, frame, seed, progress=progress))
    return min(poses, key=lambda x: x[1].residual)


def register_poses(
    suspect_V: np.ndarray,
    suspect_F: np.ndarray,
    frame: SurfaceFrame,
    seed: int = 0,
    max_poses: int = POSES,
    progress: Progress = None,
) -> Iterator[tuple[np.ndarray, RegistrationInfo]]:
    """The plausible poses of the suspect in the reference frame, reflections included, at most
    ``max_poses``, each as (suspect_V mapped, (n, 3) float64; how). See the module docstring.

    A generator: a copy whose identity start is already at the sampling noise gets that pose first,
    before any other start is tried (a reader that finds its mark there stops); then the distinct refined
    poses whose residual is within ``POSE_RATIO`` of the best, by increasing residual. The surface alone
    cannot tell the poses of a (nearly) symmetric shape apart: the reader's mark does. ``progress(fraction,
    message)`` before each stage, and 1.0 once every pose is given."""
    report = progress or no_progress
    report(0.0, "aligning: from the pose it has")
    ref_P, ref_N, ref_c, ref_A, ref_s = frame.points, frame.normals, frame.centroid, frame.axes, frame.scale
    V = np.asarray(suspect_V, np.float64)
    S, _ = sample_surface(V, suspect_F, SUSPECT_SAMPLES, seed)
    c, A, s = _pca(S)
    k_pca = ref_s / max(s, 1e-300)
    low, high = 0.3 * k_pca, 3.0 * k_pca

    def plausible(k: float) -> bool:
        """A fit whose scale is far from the PCA one collapsed (k -> 0 maps every point near one spot,
        a tiny residual) or exploded: not a fit."""
        return low < k < high

    floor = frame.floor
    index = PointIndex(ref_P)  # one tree over the key's samples for every ICP iteration of every start
    ends = c + s * np.vstack([np.zeros(3), A])  # (4, 3): where two poses are compared

    def distinct(fit, others) -> bool:
        X = fit[2] * ends @ fit[1].T + fit[3]
        return all(np.abs(X - (o[2] * ends @ o[1].T + o[3])).max() > DISTINCT * ref_s for o in others)

    def refine(finalists: list) -> list:
        fits = _icp(
            S, index, ref_N, [x[1:4] for x in finalists], ref_s, ICP_ITERATIONS, track=True, abandon=(low, high)
        )
        return sorted(
            (
                (name, R, k, t, res)
                for (name, *_), (R, k, t, res) in zip(finalists, fits)
                if plausible(k) and res < np.inf
            ),
            key=lambda x: x[4],
        )

    def pose(fit) -> tuple[np.ndarray, RegistrationInfo]:
        name, R, k, t, res = fit
        return k * V @ R.T + t, RegistrationInfo(
            rotation=R, scale=k, translation=t, residual=res, init=name, mirrored=bool(np.linalg.det(R) < 0)
        )

    given = []  # the poses yielded so far
    identity = []  # (not tried on a copy whose size is not the reference's: it cannot be in the key's frame)
    if plausible(1.0):
        identity = [("identity", *_icp(S, index, ref_N, [(np.eye(3), 1.0, np.zeros(3))], ref_s, COARSE_ITERATIONS)[0])]
    if identity and plausible(identity[0][2]) and identity[0][4] < 1.5 * floor:  # already aligned (sampling noise)
        given = refine(identity)[:1]
        yield from map(pose, given)
    report(0.1, "aligning: from its principal axes")
    starts = _pca_starts("pca", ref_c, ref_A, ref_s, c, A, s)
    if _equal_spreads(S, c, A):  # a round or square section: PCA cannot tell the turns about its axis apart
        T, _ = sample_surface(V, suspect_F, ANGLE_SAMPLES, seed + 1)  # (and a finer frame: the signature is
        frame_T = _pca(T)  # sensitive to the centroid and the axis)
        for axis in _equal_spreads(T, *frame_T[:2]):
            starts += _angular_starts(ref_P, ref_c, ref_A, ref_s, T, *frame_T, axis)
    fits = _icp(S[::COARSE_STEP], index, ref_N, [x[1:] for x in starts], ref_s, COARSE_ITERATIONS)
    coarse = sorted(
        [x for x in identity + [(name, *fit) for (name, *_), fit in zip(starts, fits)] if plausible(x[2])],
        key=lambda x: x[4],
    )
    finalists = []
    for fit in coarse:  # the distinct coarse fits near the best, best first
        if fit[4] <= COARSE_RATIO * coarse[0][4] and len(finalists) < max_poses and distinct(fit, finalists):
            finalists.append(fit)
    if not finalists:
        finalists = [starts[0] + (np.inf,)]
    report(0.3, "aligning: as a cropped copy")
    if not coarse or not coarse[0][4] < 2.0 * floor:  # not at the sampling noise: maybe cropped and moved
        sub = slice(None, None, 3)
        cuts = _cut_starts(ref_P, S, c, A, s)
        fits = _icp(
            S[::SCREEN_STEP], PointIndex(ref_P[sub]), ref_N[sub], [x[1:] for x in cuts], ref_s, COARSE_ITERATIONS
        )  # every cut start at once: one tree query per iteration
        screened = [(name, *fit) for (name, *_), fit in zip(cuts, fits) if plausible(fit[1])]
        finalists += sorted(screened, key=lambda x: x[4])[:CUT_FINALISTS]
    report(0.5, "aligning: refining")
    refined = refine(finalists)
    if not refined:  # nothing plausible: the best of the finalists as they are, for a reader to say so
        R, k, t = finalists[0][1:4]
        yield pose(("none plausible", R, k, t, np.inf))
        report(1.0, "aligned")
        return
    for fit in refined:
        if len(given) >= max_poses or fit[4] > POSE_RATIO * refined[0][4]:
            break
        if distinct(fit, given):
            given.append(fit)
            yield pose(fit)
    report(1.0, "aligned")


def _pca_starts(label: str, ref_c, ref_A, ref_s, c, A, s) -> list:
    """Similarity starts mapping a PCA frame (c, A, s) onto a reference one, for the 8 sign flips (both
    frames are right-handed: the flips of an odd number of axes mirror)."""
    k = ref_s / max(s, 1e-300)
    out = []
    for signs in SIGNS:
        R = ref_A.T @ np.diag(signs) @ A  # rows of A are the axes
        out.append((f"{label}{signs}", R, k, ref_c - k * R @ c))
    return out


def _equal_spreads(P: np.ndarray, c: np.ndarray, A: np.ndarray) -> tuple[int, ...]:
    """The PCA axes (indices into the rows of A) about which the points P (n, 3) of PCA frame (c, A) may
    be turned by any angle without PCA telling: the third axis of each pair of axes whose spreads differ by
    less than ``EQUAL_SPREAD`` (a round or square section)."""
    sd = np.sqrt(np.maximum(((P - c) @ A.T).var(axis=0), 1e-300))
    return tuple(
        3 - i - j for i in range(3) for j in range(i + 1, 3) if max(sd[i], sd[j]) < EQUAL_SPREAD * min(sd[i], sd[j])
    )


def _angular_starts(ref_P: np.ndarray, ref_c, ref_A, ref_s, T: np.ndarray, c, A, s, axis: int) -> list:
    """Similarity starts turning the suspect (samples T (m, 3), PCA frame c, A, s) about its PCA axis ``axis``
    onto the reference (samples ref_P (n, 3), PCA frame ref_c, ref_A, ref_s), at the best turns by the circular
    cross-correlation of angular signatures (``_signature``).

    In both PCA frames, divided by the scale, a point has an angle about the axis, a distance from it and a
    height along it. The reference's coordinates y follow from the suspect's z by y = M z, M a turn by phi
    about the axis, the axis kept or reversed (sigma = +-1), the angle kept or reversed (tau = +-1; M mirrors
    when sigma tau = -1). For each (sigma, tau), the suspect's signature with its angles times tau and heights
    times sigma is correlated with the reference's over every turn at once (FFT); each correlation's best
    ``ANGLE_PEAKS`` peaks (``ANGLE_APART`` apart) that reach ``ANGLE_SHARE`` of the best of all four give the
    turns, best first: an n-fold part has n peaks of about equal height per case, and a part with mirror planes
    has them in two or four cases, of which the mark is in one."""
    i, j = (q for q in range(3) if q != axis)
    th_r, rho_r, h_r = _cylindrical(ref_P, ref_c, ref_A, ref_s, axis)
    th_s, rho_s, h_s = _cylindrical(T, c, A, s, axis)
    box = (float(rho_r.max()), float(h_r.min()), float(h_r.max()))
    ref = np.fft.rfft(_signature(th_r, rho_r, h_r, box), axis=0)
    apart = int(ANGLE_APART * ANGLE_BINS / 360.0)
    peaks = []  # (correlation, sigma, tau, angle in bins)
    for sigma in (1, -1):
        for tau in (1, -1):
            sus = np.fft.rfft(_signature(tau * th_s, rho_s, sigma * h_s, box), axis=0)
            C = np.fft.irfft(ref * np.conj(sus), n=ANGLE_BINS, axis=0).sum(axis=1)  # C[n] = sum_m ref[m + n] sus[m]
            D = C.copy()
            for _ in range(ANGLE_PEAKS):
                p = int(np.argmax(D))
                a, b, d = C[p - 1], C[p], C[(p + 1) % ANGLE_BINS]  # the peak between bins (a parabola)
                curv = a - 2.0 * b + d
                peaks.append((b, sigma, tau, p + (0.5 * (a - d) / curv if curv < 0 else 0.0)))
                D[np.arange(p - apart, p + apart + 1) % ANGLE_BINS] = -np.inf
    best = max(x[0] for x in peaks)
    k = ref_s / max(s, 1e-300)
    out = []
    for _, sigma, tau, n in sorted((x for x in peaks if x[0] >= ANGLE_SHARE * best), key=lambda x: -x[0]):
        phi = 2.0 * np.pi * n / ANGLE_BINS
        M = np.zeros((3, 3))
        M[axis, axis] = sigma
        M[i, i], M[i, j], M[j, i], M[j, j] = np.cos(phi), -tau * np.sin(phi), np.sin(phi), tau * np.cos(phi)
        R = ref_A.T @ M @ A
        out.append((f"turn{axis}({sigma},{tau})@{round(np.degrees(phi)) % 360}", R, k, ref_c - k * R @ c))
    return out


def _cylindrical(P: np.ndarray, c, A, s, axis: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Angle about the PCA axis ``axis``, distance from it and height along it of the points P (n, 3) in
    the PCA frame (c, A, s), divided by the scale: three (n,) float64."""
    i, j = (q for q in range(3) if q != axis)
    Z = (P - c) @ A.T / s
    return np.arctan2(Z[:, j], Z[:, i]), np.hypot(Z[:, i], Z[:, j]), Z[:, axis]


def _signature(theta: np.ndarray, rho: np.ndarray, h: np.ndarray, box: tuple[float, float, float]) -> np.ndarray:
    """How the points (angle, distance, height) (n,) each lie around an axis: their density over
    ``ANGLE_BINS`` angles x (``RING_BINS`` distances in [0, box[0]] x ``HEIGHT_BINS`` heights in
    [box[1], box[2]]), each point spread linearly over its 8 nearest bins (a point on a flat face must not
    jump a bin for a small shift), blurred by ``ANGLE_BLUR`` along the angle, less each column's mean over
    the angles (what is round carries no turn): (ANGLE_BINS, RING_BINS * HEIGHT_BINS) float64."""
    x = theta / (2.0 * np.pi) % 1.0 * ANGLE_BINS
    a0 = np.floor(x).astype(np.int64)
    wa = x - a0
    a0 %= ANGLE_BINS
    corners = []
    for value, lo, hi, n in ((rho, 0.0, box[0], RING_BINS), (h, box[1], box[2], HEIGHT_BINS)):
        u = np.clip((value - lo) / max(hi - lo, 1e-300) * (n - 1), 0.0, n - 1 - 1e-9)
        b = np.floor(u).astype(np.int64)
        corners.append(((b, 1.0 - (u - b)), (b + 1, u - b)))
    cell, weight = [], []
    for (r, wr), (q, wq) in itertools.product(*corners):
        for a, w in ((a0, 1.0 - wa), ((a0 + 1) % ANGLE_BINS, wa)):
            cell.append(a * (RING_BINS * HEIGHT_BINS) + r * HEIGHT_BINS + q)
            weight.append(w * wr * wq)
    H = np.bincount(
        np.concatenate(cell), np.concatenate(weight), minlength=ANGLE_BINS * RING_BINS * HEIGHT_BINS
    ).reshape(ANGLE_BINS, RING_BINS * HEIGHT_BINS)
    f = np.fft.rfftfreq(ANGLE_BINS, 1.0 / ANGLE_BINS)  # cycles per turn
    H = np.fft.irfft(
        np.fft.rfft(H, axis=0) * np.exp(-0.5 * (2.0 * np.pi * f * ANGLE_BLUR / 360.0) ** 2)[:, None],
        n=ANGLE_BINS,
        axis=0,
    )
    return H - H.mean(axis=0)


def _cut_starts(ref_P: np.ndarray, S: np.ndarray, c, A, s) -> list:
    """Starts from the plane cuts of the reference samples whose PCA shape best matches the
    suspect's (S, with PCA frame c, A, s)."""
    i = np.arange(CUT_DIRECTIONS) + 0.5
    z = 1.0 - 2.0 * i / CUT_DIRECTIONS
    th = np.pi * (1.0 + 5.0**0.5) * i
    dirs = np.stack([np.sqrt(1.0 - z * z) * np.cos(th), np.sqrt(1.0 - z * z) * np.sin(th), z], axis=1)
    proj = ref_P @ dirs.T
    # a cut keeps the points at or below the q-quantile of their projections; that quantile lies between
    # the order statistics floor(q (n - 1)) and the next, and no projection lies strictly between them,
    # so the cut keeps the points up to the first (np.quantile would import numpy.ma: 12 ms of a fresh
    # process; 1e-9: a product q (n - 1) that is a whole number but rounds below it)
    rows = np.ascontiguousarray(proj.T)
    rows.sort(axis=1)
    kth = np.floor(np.asarray(CUT_KEEP) * (len(ref_P) - 1) + 1e-9).astype(np.int64)
    cuts = proj <= rows[:, kth].T[:, None, :]  # (keep, point, direction)
    cuts = cuts.transpose(0, 2, 1).reshape(-1, len(ref_P))
    dist = np.abs(_log_spread(ref_P, cuts) - _log_spread(S, np.ones((1, len(S)), bool))).sum(axis=1)
    out = []
    for j in np.argsort(dist, kind="stable")[:CUT_CANDIDATES]:
        out += _pca_starts(f"cut{j}", *_pca(ref_P[cuts[j]]), c, A, s)
    return out


def _log_spread(P: np.ndarray, masks: np.ndarray) -> np.ndarray:
    """Log ratios of consecutive PCA variances of each masked subset of P (rows of ``masks``): a
    scale- and rotation-free shape, (subsets, 2)."""
    W = masks.astype(np.float64)
    n = W.sum(axis=1)[:, None]
    mu = W @ P / n
    Pc = P - P.mean(axis=0)
    C = (W @ (Pc[:, :, None] * Pc[:, None, :]).reshape(len(P), 9)).reshape(-1, 3, 3) / n[..., None]
    m = mu - P.mean(axis=0)
    w = np.linalg.eigvalsh(C - m[:, :, None] * m[:, None, :])[:, ::-1]
    return np.log(np.maximum(w[:, :2], 1e-300) / np.maximum(w[:, 1:], 1e-300))


# --------------------------------------------------------------------------- helpers


def _self_floor(P: np.ndarray, V: np.ndarray, F: np.ndarray, seed: int) -> float:
    Q, _ = sample_surface(V, F, SUSPECT_SAMPLES, seed + 1)
    _, d2 = nearest(P, Q)
    return float(np.sqrt(np.mean(np.sort(d2)[: int(TRIM * len(d2))])))


def _pca(P: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Centroid, axes (rows, by decreasing variance, right-handed) and scale (RMS radius)."""
    c = P.mean(axis=0)
    C = np.cov((P - c).T, bias=True)
    w, U = np.linalg.eigh(C)
    order = np.argsort(w)[::-1]
    A = U[:, order].T
    # deterministic signs: third-moment skew positive along the first two axes
    proj = (P - c) @ A.T
    for i in range(2):
        if np.mean(proj[:, i] ** 3) < 0:
            A[i] = -A[i]
    A[2] = np.cross(A[0], A[1])
    return c, A, float(np.sqrt(max(w.sum(), 1e-300)))


def _icp(
    S: np.ndarray,
    index: PointIndex,
    ref_N: np.ndarray,
    starts: list,
    ref_s: float,
    iterations: int,
    track: bool = False,
    abandon: tuple[float, float] | None = None,
) -> list[tuple[np.ndarray, float, np.ndarray, float]]:
    """Trimmed point-to-plane similarity ICP of the sources S (m, 3) onto the reference points of
    ``index`` (n, 3) with normals ref_N (n, 3), from every start (R (3, 3), k, t (3,)) at once (each
    stops when its own step is negligible, as it would alone). Returns (R, k, t, residual) per
    start; the residual is the trimmed RMS point-to-point distance / ref_s. With ``abandon`` (a
    plausible scale range (low, high)), from ``ABANDON_AFTER`` iterations on, a start whose residual
    is more than ``ABANDON_RATIO`` times the smallest of the starts with a plausible scale stops
    there, with an infinite residual.

    Only the ``TRIM`` share of closest pairs is used, so after the first iteration each start's
    search is bounded by its last trim distance plus the farthest any source point just moved: its
    closest pairs are still inside that bound, so they are exactly those of an unbounded search."""
    ref_P = index.points
    R = np.array([x[0] for x in starts], np.float64).reshape(-1, 3, 3)
    k = np.array([x[1] for x in starts], np.float64)
    t = np.array([x[2] for x in starts], np.float64).reshape(-1, 3)
    n_keep = min(max(int(TRIM * len(S)), 7), len(S))
    X_last = np.zeros((len(k), len(S), 3))  # each start's points at its last search
    trim = np.full(len(k), np.inf)  # and the distance of its farthest kept pair then (inf: no bound)
    # long refinements converge: their points mostly keep their nearest, searched again only when
    # it can have changed (MovingNearest); the short coarse runs move too much for that to pay
    tracker = MovingNearest(index, len(k), len(S)) if track else None

    def search(ids: np.ndarray):
        """The starts ``ids``' points at their current pose (b, m, 3), their closest reference points
        and squared distances (b, m), and the indices of the kept pairs (b, n_keep), the farthest
        last (a partition, not a sort: the pairs' order does not matter)."""
        X = (k[ids, None, None] * S) @ R[ids].transpose(0, 2, 1) + t[ids, None, :]
        bound = trim[ids] + np.linalg.norm(X - np.take(X_last, ids, axis=0), axis=2).max(axis=1)
        j, d2 = _closest(index, tracker, ids, X, bound, n_keep)
        keep = np.argpartition(d2, n_keep - 1, axis=1)[:, :n_keep]
        X_last[ids], trim[ids] = X, np.sqrt(d2[np.arange(len(ids)), keep[:, -1]])
        return X, j, d2, keep

    active = np.arange(len(k))
    rms = np.full(len(k), np.inf)  # each start's trimmed RMS residual at its last search
    alive = np.ones(len(k), bool)  # not abandoned
    for it in range(iterations):
        if abandon is not None and it >= ABANDON_AFTER:
            fair = alive & (abandon[0] < k) & (k < abandon[1])
            if fair.any():
                hopeless = rms > ABANDON_RATIO * rms[fair].min()
                alive &= ~hopeless
                active = active[~hopeless[active]]
        if len(active) == 0:
            break
        X, j, d2, keep = search(active)
        if abandon is not None:
            rms[active] = np.sqrt(np.mean(np.take_along_axis(d2, keep, axis=1), axis=1))
        flat = np.arange(len(active))[:, None] * len(S) + keep  # the kept pairs in X, j (np.take: fast)
        x = np.take(X.reshape(-1, 3), flat, axis=0)
        jj = np.take(j, flat)
        q, n = np.take(ref_P, jj, axis=0), np.take(ref_N, jj, axis=0)
        m = x.mean(axis=1)
        xc = x - m[:, None, :]  # linearise about the sources' centroid: better conditioned
        r = np.einsum("bij,bij->bi", q - x, n)
        J = np.empty(xc.shape[:2] + (7,))  # scale, rotation (xc x n, as np.cross), translation
        J[..., 0] = np.einsum("bij,bij->bi", xc, n)
        (a0, a1, a2), (n0, n1, n2) = np.moveaxis(xc, 2, 0), np.moveaxis(n, 2, 0)
        J[..., 1], J[..., 2], J[..., 3] = a1 * n2 - a2 * n1, a2 * n0 - a0 * n2, a0 * n1 - a1 * n0
        J[..., 4:] = n
        sol = _lstsq(J, r)
        ds, w, dt = sol[:, 0], sol[:, 1:4], sol[:, 4:7]
        angle = np.linalg.norm(w, axis=1)
        dR = _rotations(w, angle)
        # x -> (1 + ds) dR (x - m) + m + dt, applied to the current transform
        f = 1.0 + ds
        t[active] = f[:, None] * np.einsum("bij,bj->bi", dR, t[active] - m) + m + dt
        R[active] = dR @ R[active]
        k[active] = k[active] * f
        moving = (np.abs(ds) >= 1e-7) | (angle >= 1e-7) | (np.linalg.norm(dt, axis=1) >= 1e-7 * ref_s)
        active = active[moving]
    done = np.flatnonzero(alive)
    _, _, d2, keep = search(done)
    res = np.full(len(k), np.inf)
    res[done] = (
        np.sqrt(np.mean(np.take(d2, np.arange(len(done))[:, None] * len(S) + keep), axis=1)) / ref_s
    )  # point-to-point: no sliding
    return [(R[b], float(k[b]), t[b], float(res[b])) for b in range(len(k))]


def _closest(
    index: PointIndex, tracker: MovingNearest | None, ids: np.ndarray, X: np.ndarray, bound: np.ndarray, n_keep: int
) -> tuple[np.ndarray, np.ndarray]:
    """Nearest reference point (b, m) and squared distance (b, m) of the starts ``ids``' points X
    (b, m, 3), searched within each start's ``bound`` (b,) (beyond it: -1, inf); a start with fewer
    than ``n_keep`` points inside is searched again without a bound. With a ``tracker``, the same
    answers, searching only the points whose nearest can have changed."""
    if not np.all(np.isfinite(bound)):
        return index.nearest(X) if tracker is None else tracker.nearest(ids, X, np.full(len(X), np.inf))
    ub = bound * (1.0 + 1e-9) + 1e-300
    if tracker is None:
        j, d2 = index.nearest_rows(X, ub)
    else:
        j, d2 = tracker.nearest(ids, X, ub)
    short = np.flatnonzero(np.count_nonzero(d2 < np.inf, axis=1) < n_keep)
    for b in short:
        j[b], d2[b] = index.nearest(X[b])
    return j, d2


def _lstsq(J: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Least-squares solutions of J[b] x = r[b] for every b at once: J (b, m, p), r (b, m) -> (b, p).

    Normal equations with the columns scaled to unit length (the scale, rotation and translation
    columns differ by the mesh's size), solved through the eigenvalues of the small (p, p) systems:
    directions the data do not constrain (eigenvalue below 1e-10 of the largest; a flat patch leaves
    the in-plane motions free) get no step, as a minimum-norm solution gives none."""
    JT = J.transpose(0, 2, 1)
    A = JT @ J  # (b, p, p)
    norm = np.sqrt(np.diagonal(A, axis1=1, axis2=2))
    norm = np.where(norm > 0, norm, 1.0)
    A = A / (norm[:, :, None] * norm[:, None, :])
    g = (JT @ r[:, :, None])[:, :, 0] / norm
    w, U = np.linalg.eigh(A)
    inv = np.where(w > 1e-10 * w[:, -1:], 1.0 / np.where(w > 0, w, 1.0), 0.0)
    x = (U @ (inv * (U.transpose(0, 2, 1) @ g[:, :, None])[:, :, 0])[:, :, None])[:, :, 0]
    return x / norm


def similarity_fit(src: np.ndarray, dst: np.ndarray, mirror: bool = False) -> tuple[np.ndarray, float, np.ndarray]:
    """Least-squares similarity (R, k, t) with dst ~ k R src + t for paired points src, dst (n, 3)
    (Umeyama 1991): the exact registration when the correspondences are known. R is a rotation, or with
    ``mirror`` any orthogonal matrix (det -1 when dst is a mirror image of src)."""
    ms, md = src.mean(axis=0), dst.mean(axis=0)
    a, b = src - ms, dst - md
    U, sv, Wt = np.linalg.svd(b.T @ a)
    D = np.diag([1.0, 1.0, 1.0 if mirror else (np.sign(np.linalg.det(U @ Wt)) or 1.0)])
    R = U @ D @ Wt
    k = float(np.trace(np.diag(sv) @ D) / max(np.einsum("ij,ij->", a, a), 1e-300))
    return R, k, md - k * R @ ms


def _rotations(w: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotation matrices (b, 3, 3) by the angles ``angle`` (b,) about the axes w / angle (w (b, 3));
    the identity where the angle is below 1e-15 (Rodrigues' formula)."""
    small = angle <= 1e-15
    a = np.where(small, 1.0, angle)
    u = np.where(small[:, None], 0.0, w / a[:, None])
    K = np.zeros((len(w), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -u[:, 2], u[:, 1], -u[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = u[:, 2], -u[:, 1], u[:, 0]
    return np.eye(3) + np.sin(a)[:, None, None] * K + (1.0 - np.cos(a))[:, None, None] * K @ K
