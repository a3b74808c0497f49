"""Register a suspect mesh to the marked mesh's frame before reading a robust watermark.

The key stores a reference frame of the MARKED surface: ~1,000 seeded surface samples with their
normals, plus the centroid, PCA axes and scale of the surface (area-weighted, so that re-meshing,
simplification or subdivision do not move them). ``register`` maps a suspect into that frame:

1. Initial guesses: the identity (most copies are not rotated; PCA is useless on a copy cropped to
   half), and the PCA alignment (centroid, axes, scale from the eigenvalues) with the 4 proper sign
   flips of the axes.
2. Each guess is refined by trimmed similarity ICP, point-to-plane against the reference normals
   (sampling offsets along the surface then cost nothing, unlike point-to-point): the closest
   ``TRIM`` share of pairs drive a linearised least-squares step (scale, rotation, translation).
   Suspect samples are the sources and the reference points the targets, so a cropped suspect still
   finds a counterpart for all its points.
3. The guess with the smallest trimmed point-to-point residual wins (point-to-point here, so that a
   fit sliding along a flat part cannot look perfect; a guess whose scale collapsed or exploded is
   dropped); the identity is kept without trying the others when its residual is already at the
   sampling noise (two samplings of the same surface, stored in the key as ``floor``).
   The winner gets 30 more ICP iterations. Accuracy is ~0.1 % of the size: enough for the robust
   reading, which is relative to a ring around each site.
4. A copy cut by a plane AND moved defeats both starts: its PCA is not the reference's. When no start
   reaches twice the sampling noise, the reference samples are cut by ``CUT_DIRECTIONS`` planes at
   ``CUT_KEEP`` shares each; the cuts whose PCA shape (eigenvalue ratios) is closest to the suspect's
   give ``CUT_CANDIDATES`` x 4 more starts, screened by ICP on a third of the samples. The best
   ``CUT_FINALISTS`` and the best plain start are refined in full, and the smallest residual wins.

Nearest neighbours are chunked brute force over a few thousand points (numpy only, no scipy).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .sampling import sample_surface
from .spatial import nearest


TRIM = 0.65  # share of the closest pairs used by ICP (robust to cropping to half)
ICP_ITERATIONS = 30
COARSE_ITERATIONS = 8
SUSPECT_SAMPLES = 1500
CUT_DIRECTIONS = 128  # plane directions tried for cropped-and-moved copies (Fibonacci sphere)
CUT_KEEP = (0.5, 0.6, 0.7, 0.8, 0.9)  # shares of the reference kept by each cut
CUT_CANDIDATES = 16  # cuts whose PCA shape is closest to the suspect's
CUT_FINALISTS = 4  # screened cut starts refined in full
SIGNS = ((1, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1))  # proper sign flips of PCA axes


@dataclass
class RegistrationInfo:
    """How the suspect was aligned: x_ref = scale * R @ x + t."""

    rotation: np.ndarray
    scale: float
    translation: np.ndarray
    residual: float  # trimmed RMS point-to-point residual / reference scale
    init: str  # "identity" or "pca<signs>"


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
        return {"points": self.points.tolist(), "normals": self.normals.tolist(),
                "centroid": self.centroid.tolist(), "axes": self.axes.tolist(), "scale": self.scale,
                "floor": self.floor}

    @classmethod
    def from_json(cls, d: dict) -> "SurfaceFrame":
        """The frame from its JSON form; ValueError, KeyError or TypeError when it is not one."""
        shapes = {"points": (-1, 3), "normals": (-1, 3), "centroid": (3,), "axes": (3, 3)}
        arrays = {k: np.asarray(d[k], np.float64).reshape(shp) for k, shp in shapes.items()}
        frame = cls(**arrays, scale=float(d["scale"]), floor=float(d.get("floor", 0.0)))
        if not all(np.all(np.isfinite(v)) for v in (*arrays.values(), frame.scale, frame.floor)) \
                or frame.scale <= 0 or len(frame.points) != len(frame.normals) or len(frame.points) < 3:
            raise ValueError("registration frame")
        return frame


def surface_frame(vertices: np.ndarray, faces: np.ndarray, n_samples: int, seed: int) -> SurfaceFrame:
    """The reference frame of a surface: ``n_samples`` area-uniform samples and their PCA."""
    P, N = sample_surface(vertices, faces, n_samples, seed, normals=True)
    centroid, axes, scale = _pca(P)
    return SurfaceFrame(points=np.round(P, 9), normals=np.round(N, 6), centroid=centroid, axes=axes,
                        scale=scale, floor=_self_floor(P, vertices, faces, seed) / scale)


def register(suspect_V: np.ndarray, suspect_F: np.ndarray, frame: SurfaceFrame, seed: int = 0
             ) -> tuple[np.ndarray, RegistrationInfo]:
    """The suspect's vertices mapped into the reference frame, and how (see the module docstring).

    suspect_V : (n, 3) float64, suspect_F : (m, 3) int64; returns (n, 3) float64."""
    ref_P, ref_N, ref_c, ref_A, ref_s = frame.points, frame.normals, frame.centroid, frame.axes, frame.scale
    V = np.asarray(suspect_V, np.float64)
    S, _ = sample_surface(V, suspect_F, SUSPECT_SAMPLES, seed)
    c, A, s = _pca(S)
    inits = [("identity", np.eye(3), 1.0, np.zeros(3))] + _pca_starts("pca", ref_c, ref_A, ref_s, c, A, s)
    k_pca = ref_s / max(s, 1e-300)

    def plausible(k: float) -> bool:
        """A fit whose scale is far from the PCA one collapsed (k -> 0 maps every point near one spot,
        a tiny residual) or exploded: not a fit."""
        return 0.3 * k_pca < k < 3.0 * k_pca

    floor = frame.floor
    best = None
    for name, R, k, t in inits:
        R, k, t, res = _icp(S, ref_P, ref_N, R, k, t, ref_s, COARSE_ITERATIONS)
        if not plausible(k):
            continue
        if best is None or res < best[4]:
            best = (name, R, k, t, res)
        if name == "identity" and res < 1.5 * floor:  # already aligned: at the sampling noise
            break
    if best is None:
        best = inits[1] + (np.inf,)
    finalists = [best]
    if not best[4] < 2.0 * floor:  # not at the sampling noise: maybe cropped and moved
        sub = slice(None, None, 3)
        screened = []
        for name, R, k, t in _cut_starts(ref_P, S, c, A, s):
            R, k, t, res = _icp(S[sub], ref_P[sub], ref_N[sub], R, k, t, ref_s, COARSE_ITERATIONS)
            if plausible(k):
                screened.append((name, R, k, t, res))
        finalists += sorted(screened, key=lambda x: x[4])[:CUT_FINALISTS]
    refined = []
    for name, R, k, t, _ in finalists:
        R, k, t, res = _icp(S, ref_P, ref_N, R, k, t, ref_s, ICP_ITERATIONS)
        refined.append((not plausible(k), res, len(refined), name, R, k, t))  # plausible fits first
    _, res, _, name, R, k, t = min(refined)
    return k * V @ R.T + t, RegistrationInfo(rotation=R, scale=k, translation=t, residual=res, init=name)


def _pca_starts(label: str, ref_c, ref_A, ref_s, c, A, s) -> list:
    """Similarity starts mapping a PCA frame (c, A, s) onto a reference one, for the 4 sign flips."""
    out = []
    for signs in SIGNS:
        R = ref_A.T @ np.diag(signs) @ A  # rows of A are the axes
        if np.linalg.det(R) < 0:
            R = ref_A.T @ np.diag(signs) @ np.diag([1, 1, -1]) @ A
        k = ref_s / max(s, 1e-300)
        out.append((f"{label}{signs}", R, k, ref_c - k * R @ c))
    return out


def _cut_starts(ref_P: np.ndarray, S: np.ndarray, c, A, s) -> list:
    """Starts from the plane cuts of the reference samples whose PCA shape best matches the
    suspect's (S, with PCA frame c, A, s)."""
    i = np.arange(CUT_DIRECTIONS) + 0.5
    z = 1.0 - 2.0 * i / CUT_DIRECTIONS
    th = np.pi * (1.0 + 5.0**0.5) * i
    dirs = np.stack([np.sqrt(1.0 - z * z) * np.cos(th), np.sqrt(1.0 - z * z) * np.sin(th), z], axis=1)
    proj = ref_P @ dirs.T
    cuts = proj <= np.quantile(proj, CUT_KEEP, axis=0)[:, None, :]  # (keep, point, direction)
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
    C = np.einsum("cn,ni,nj->cij", W, P - P.mean(axis=0), P - P.mean(axis=0)) / n[..., None]
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


def _icp(S, ref_P, ref_N, R, k, t, ref_s, iterations):
    """Trimmed point-to-plane similarity ICP from (R, k, t); returns (R, k, t, residual)."""
    res = np.inf
    for _ in range(iterations):
        X = k * S @ R.T + t
        j, d2 = nearest(ref_P, X)
        keep = np.argsort(d2)[: max(int(TRIM * len(X)), 7)]
        x, q, n = X[keep], ref_P[j[keep]], ref_N[j[keep]]
        xc = x - x.mean(axis=0)  # linearise about the sources' centroid: better conditioned
        r = np.einsum("ij,ij->i", q - x, n)
        J = np.concatenate([np.einsum("ij,ij->i", xc, n)[:, None], np.cross(xc, n), n], axis=1)
        sol, *_ = np.linalg.lstsq(J, r, rcond=None)
        ds, w, dt = sol[0], sol[1:4], sol[4:7]
        angle = float(np.linalg.norm(w))
        dR = _rodrigues(w / angle, angle) if angle > 1e-15 else np.eye(3)
        m = x.mean(axis=0)
        # x -> (1 + ds) dR (x - m) + m + dt, applied to the current transform
        f = 1.0 + ds
        R = dR @ R
        k = k * f
        t = f * dR @ (t - m) + m + dt
        res = float(np.sqrt(np.mean(r**2))) / ref_s
        if abs(ds) < 1e-7 and angle < 1e-7 and np.linalg.norm(dt) < 1e-7 * ref_s:
            break
    X = k * S @ R.T + t
    j, d2 = nearest(ref_P, X)
    keep = np.argsort(d2)[: max(int(TRIM * len(X)), 7)]
    res = float(np.sqrt(np.mean(d2[keep]))) / ref_s  # trimmed point-to-point: no sliding
    return R, k, t, res


def similarity_fit(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """Least-squares similarity (R, k, t) with dst ~ k R src + t for paired points (Umeyama 1991):
    the exact registration when the correspondences are known."""
    ms, md = src.mean(axis=0), dst.mean(axis=0)
    a, b = src - ms, dst - md
    U, sv, Wt = np.linalg.svd(b.T @ a)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Wt)) or 1.0])
    R = U @ D @ Wt
    k = float(np.trace(np.diag(sv) @ D) / max(np.einsum("ij,ij->", a, a), 1e-300))
    return R, k, md - k * R @ ms


def _rodrigues(axis: np.ndarray, angle: float) -> np.ndarray:
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
