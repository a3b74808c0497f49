"""One analysis of an asset, then one cheap marked copy per recipient.

``analyse_asset`` runs the robust scheme's analysis once (``pmwm.schemes.robust.embed.analyse``:
sites, frames, samples, bump and swirl fields, protected rings), decides once which sites carry a
bump and a swirl (on a keyed reference copy, so that the decision does not depend on any recipient),
builds the progressive mesh once (on the unmarked asset, the sites protected: connectivity and
records are the same for every copy) and the tracing key. ``AssetAnalysis.copy`` then marks a
recipient's copy: D = sum over samples of sign[site] * field (a bincount), float32 positions, the
progressive mesh with the copy's positions, and the bytes of its files (binary PLY and .pmwm).
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
from dataclasses import dataclass
from typing import Optional

import numpy as np

from ..adjacency import build_adjacency
from ..atomic import atomic_output
from ..background import Later, beside
from ..base import Progress, check_options, make_key, no_progress
from ..errors import PayloadError
from ..key import WatermarkKey, derive_seed, make_secret, mesh_sha256
from ..meshio import ply_parts
from ..progressive import to_bytes
from ..progressive import ProgressiveMesh, base_vertex_count, build_progressive_mesh, with_positions
from ..register import surface_frame
from ..spatial import loading_engine
from ..schemes.robust.embed import DEFAULT_STRENGTH, REF_POINTS, SITES_PER_BIT, SiteAnalysis, analyse
from ..schemes.robust.keydata import RobustKeyData
from ..schemes.robust.read import NAME
from ..validate import MAX_COORDINATE, check_mesh
from .codes import codeword

__all__ = ["FingerprintOptions", "AssetAnalysis", "CopyFiles", "analyse_asset"]


@dataclass
class FingerprintOptions:
    """Options of a fingerprinted asset. strength: as ``pmwm.EmbedOptions`` (bump and swirl
    amplitudes, robust default 2); n_sites: sites carrying the codeword (fewer on small meshes);
    base_ratio: base mesh vertices / vertices of the progressive mesh; seed: of the key's secret
    (None: fresh)."""

    strength: float = DEFAULT_STRENGTH
    n_sites: int = 64 * SITES_PER_BIT
    base_ratio: float = 0.03
    seed: Optional[int] = None

    def to_dict(self) -> dict:
        return {"strength": self.strength, "n_sites": self.n_sites, "base_ratio": self.base_ratio}


@dataclass
class CopyFiles:
    """One recipient's copy: marked vertices (n, 3) float64 (float32-exact, the asset's order), and
    the bytes of each file by suffix (".ply", and ".pmwm" when asked)."""

    vertices: np.ndarray
    files: dict


@dataclass
class AssetAnalysis:
    """An asset analysed for fingerprinting (see the module docstring). sites : the robust
    analysis; key: the tracing key (a robust key with one "bit" per site, chip +1); bump, swirl (S,)
    float64: 1 where a copy carries the site's bump / swirl, 0 where no reading would see it; pm: the
    progressive mesh every copy shares (its positions those of the unmarked asset), None when the
    analysis was asked for none (copies without .pmwm files)."""

    sites: SiteAnalysis
    key: WatermarkKey
    options: FingerprintOptions
    bump: np.ndarray
    swirl: np.ndarray
    pm: Optional[ProgressiveMesh]
    asset_sha256: str
    _ply_head: bytes = dataclasses.field(repr=False, default=b"")
    _ply_faces: bytes = dataclasses.field(repr=False, default=b"")

    @property
    def n_sites(self) -> int:
        return self.sites.n_sites

    def codeword(self, recipient: str) -> np.ndarray:
        """The recipient's codeword (S,) int8 +-1 (``pmwm.fingerprint.codes.codeword``)."""
        return codeword(self.key.secret, recipient, self.n_sites)

    def marked(self, c: np.ndarray) -> np.ndarray:
        """The copy marked with codeword c (S,) (+-1, or any real weights): (n, 3) float64."""
        c = np.asarray(c, np.float64)
        return self.sites.mark(c * self.bump, c * self.swirl)

    def copy_pm(self, marked: np.ndarray) -> ProgressiveMesh:
        """The copy's progressive mesh: the shared connectivity and records, the copy's positions
        (decodes exactly to ``marked`` in the progressive mesh's vertex order)."""
        if self.pm is None:
            raise ValueError(
                "this asset was analysed without a progressive mesh (progressive=False); "
                "analyse it with one to write .pmwm copies"
            )
        return with_positions(self.pm, marked)

    def copy(self, c: np.ndarray, pm: bool = False) -> CopyFiles:
        """The copy for codeword c (S,): its vertices and file bytes (binary PLY; .pmwm if ``pm``)."""
        X = self.marked(c)
        files = {".ply": self._ply_head + X.astype("<f4").tobytes() + self._ply_faces}
        if pm:
            files[".pmwm"] = to_bytes(self.copy_pm(X))
        return CopyFiles(X, files)

    def write_copy(self, folder, recipient: str, pm: bool = False) -> dict:
        """Write the recipient's copy to ``folder``/<recipient>.ply (and .pmwm), each atomically
        (replacing what is there); {file name: SHA-256} of what was written."""
        out = {}
        for suffix, data in self.copy(self.codeword(recipient), pm).files.items():
            name = recipient + suffix
            with atomic_output(os.path.join(os.fspath(folder), name), force=True) as tmp:
                with open(tmp, "wb") as fh:
                    fh.write(data)
            out[name] = hashlib.sha256(data).hexdigest()
        return out


def analyse_asset(
    vertices,
    faces,
    options: Optional[FingerprintOptions] = None,
    secret: Optional[str] = None,
    progress: Progress = None,
    progressive: bool = True,
) -> AssetAnalysis:
    """Analyse an asset, vertices (n, 3) float64, faces (m, 3) int64, for fingerprinting with the
    key's ``secret`` (None: drawn from ``options.seed``, or fresh). ``progressive``: build the
    progressive mesh the copies share (False: none, for copies without .pmwm files; the same sites,
    codewords and copies, the key recording the asset's own numbering as its progressive one)."""
    opts = options or FingerprintOptions()
    report = progress or no_progress
    strength = check_options(opts, DEFAULT_STRENGTH)
    if int(opts.n_sites) < 2 * SITES_PER_BIT:
        raise PayloadError(f"a fingerprint needs at least {2 * SITES_PER_BIT} sites, got {opts.n_sites}")
    V, F = check_mesh(vertices, faces, max_coordinate=MAX_COORDINATE)
    secret = secret if secret is not None else make_secret(opts.seed)
    adj = build_adjacency(F, len(V))
    # the progressive mesh every copy shares (of the unmarked asset), built beside the analysis: its set-up
    # while the sites are placed, its passes, once the readable sites are known, beside the rest
    keep = Later()
    with (
        loading_engine(),
        beside(
            progressive,
            build_progressive_mesh,
            V,
            F,
            protected=keep,
            adjacency=adj,
            base_vertices=base_vertex_count(opts.base_ratio, len(V)),
        ) as building,
    ):
        an = analyse(
            V,
            F,
            secret,
            strength,
            max(1, int(opts.n_sites) // SITES_PER_BIT),
            SITES_PER_BIT,
            report=lambda f, m: report(0.5 * f, m),
            adj=adj,
        )
        S = an.n_sites
        # which sites read: decided on a keyed reference copy, the same for every recipient
        ref = codeword(secret, "\0reference", S).astype(np.float64)
        _, (usable, centre_ok, index_ok, swirl_ok), dead, no_swirl = an.mark_readable(ref)
        if progressive:
            keep.set(an.protected(usable | centre_ok))
        frame = surface_frame(V, F, REF_POINTS, derive_seed(secret, "robust-frame") % (2**31))
        data = dataclasses.replace(
            an.site,
            bit=np.arange(S),
            chip=np.ones(S),
            usable=usable,
            centre_ok=centre_ok,
            swirl_ok=swirl_ok,
            index_ok=index_ok,
            frame=frame,
        )
        data = RobustKeyData.from_extra(data.to_extra(), S, len(V))  # as the key file will read
        pm = building.result(lambda f, m: report(0.6 + 0.35 * f, m))[0] if progressive else None
    key = make_key(
        secret, np.zeros(S, np.uint8), "bits", strength, V, F, V, an.adj, pm, np.zeros(0, np.int64), NAME, data=data
    )
    head, body = ply_parts(len(V), F, comment=b"pmwm fingerprinted copy")
    report(1.0, "analysed")
    return AssetAnalysis(
        sites=an,
        key=key,
        options=opts,
        bump=np.where(dead, 0.0, 1.0),
        swirl=np.where(dead | no_swirl, 0.0, 1.0),
        pm=pm,
        asset_sha256=mesh_sha256(V, F, "<f8"),
        _ply_head=head,
        _ply_faces=body,
    )
