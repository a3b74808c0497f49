"""Embedding the robust mark (see ``pmwm.schemes.robust``): sites, their samples, the keyed bit
layout, the bumps and swirls, the readability checks, the protected vertices and the key data.

Two steps: ``analyse`` (everything that depends on the mesh and the key's secret only: sites, their
frames and samples, the bump and swirl fields, the keyed bit layout, the protected rings) and
``SiteAnalysis.mark`` (a cheap step: the marked mesh for given per-site signs, a weighted sum over
the samples). ``embed`` runs both; ``pmwm.fingerprint`` runs the analysis once and marks one copy
per recipient. The analysis has two halves, ``place_sites`` (sites, frames, samples, protected
rings) and ``lay_out`` (bit layout, chips, fields). ``embed`` builds the progressive mesh of the
unmarked mesh in a worker thread (``pmwm.background``) from the start: its set-up runs while the first
half places the sites, its passes, once the first half has named the protected vertices, while the
second half and the marking run."""

from __future__ import annotations

import dataclasses
from typing import Callable, Optional

import numpy as np

from ...adjacency import Adjacency, build_adjacency
from ...background import Later, beside
from ...base import EmbedOptions, EmbedResult, Progress, finish_embed, mesh_key, no_progress, start_embed
from ...carriers import eligible_carriers, select_carriers
from ...errors import PayloadError
from ...features import face_cross, mean_edge_length, vertex_normals
from ...key import derive_seed, keyed_bits
from ...progressive import ProgressiveMesh, base_vertex_count, build_progressive_mesh, with_positions
from ...register import surface_frame
from ...spatial import loading_engine, min_spacing, pairs_within
from ...bch import BCHCode, payload_code
from .code import coded_bits
from .fields import OUTER, index_templates, profile, swirl, tangent_frames
from .keydata import RobustKeyData, Samples
from .layout import assign_bits
from . import selfcheck
from .read import NAME, centre_soft, host_laplacians, site_soft, swirl_soft, verify

DEFAULT_STRENGTH = 2.0
SITES_PER_BIT = 6
RADIUS_EDGES = 2.5  # bump radius in mean edge lengths
AMPLITUDE_PER_STRENGTH = 0.09  # bump amplitude per unit of strength, in mean edge lengths
SWIRL_PER_STRENGTH = 0.09  # in-surface swirl amplitude per unit of strength, in mean edge lengths
RING = 3  # protected annulus vertices per site
RING_DISTANCE = 1.3  # their distance / r
REF_POINTS = 3000  # registration samples stored in the key


@dataclasses.dataclass
class SiteAnalysis:
    """What marking needs, computed once per mesh and secret (S sites, K samples in all).

    vertices (n, 3) float64, faces (m, 3) int64, adj their adjacency; sites (S,) int64 site vertices;
    site: the key data with every reading flag False (origin, normal, radius, amplitudes, samples,
    and the keyed bit ``bit`` (S,) and ``chip`` (S,) of each site for ``n_bits`` bits); sample_site,
    sample_vertex (K,) int64; bump_field, swirl_field (K, 3) float64 the displacement of each
    sample's vertex by its site's bump and swirl for a sign of +1; ring (S, RING) int64 the protected
    annulus vertices (-1: none found)."""

    vertices: np.ndarray
    faces: np.ndarray
    adj: Adjacency
    sites: np.ndarray
    site: RobustKeyData
    n_bits: int
    sample_site: np.ndarray
    sample_vertex: np.ndarray
    bump_field: np.ndarray
    swirl_field: np.ndarray
    ring: np.ndarray

    @property
    def n_sites(self) -> int:
        return len(self.sites)

    def displacement(self, bump_sign: np.ndarray, swirl_sign: np.ndarray) -> np.ndarray:
        """The marking displacement (n, 3) float64 for per-site signs bump_sign, swirl_sign (S,)
        (+-1, or 0 for no bump / no swirl; any real factor scales that site's field)."""
        si, n = self.sample_site, len(self.vertices)
        W = bump_sign[si][:, None] * self.bump_field + swirl_sign[si][:, None] * self.swirl_field
        return np.stack([np.bincount(self.sample_vertex, weights=W[:, a], minlength=n) for a in range(3)], 1)

    def mark(self, bump_sign: np.ndarray, swirl_sign: np.ndarray) -> np.ndarray:
        """The marked mesh (n, 3) float64 (float32-exact) for per-site signs (S,)."""
        return (self.vertices + self.displacement(bump_sign, swirl_sign)).astype(np.float32).astype(np.float64)

    def readable(self, marked: np.ndarray, sign: np.ndarray) -> list[np.ndarray]:
        """Each site's own readings of ``marked`` (S,) bool each: [usable (by all samples, ring
        found), centre_ok (at the site vertex), index_ok (by index), swirl_ok (the swirl)]: clearly
        its ``sign``, or not. On small meshes a neighbour's bump may reach a site's samples and spoil
        one reading or both."""
        F, site = self.faces, self.site
        ring_found = (self.ring >= 0).all(axis=1)
        laplacians = host_laplacians(marked, F, site)
        at_vertices = site_soft(marked, F, site, True, laplacians)[0]
        usable, centre_ok = [
            ring_found & np.isfinite(soft) & (np.abs(soft - sign) < 0.5)
            for soft in (at_vertices, centre_soft(marked, site, True))
        ]
        # copies with the marked vertex order are read at every site that reads cleanly by index,
        # also where no protected ring was found (that ring only matters to coarser levels)
        index_ok = np.isfinite(at_vertices) & (np.abs(at_vertices - sign) < 0.5)
        # and by its swirl (read by vertex index): a neighbour's bump may tilt it on a small mesh
        swirl_ok = np.abs(swirl_soft(marked, F, site, laplacians)[0] - sign) < 0.5
        return [usable, centre_ok, index_ok, swirl_ok]

    def mark_readable(self, sign: np.ndarray) -> tuple[np.ndarray, list[np.ndarray], np.ndarray, np.ndarray]:
        """Mark with ``sign`` (S,) +-1, leaving out the bumps no reading uses and the swirls that do
        not read (their distortion would buy nothing): (marked (n, 3), [usable, centre_ok,
        index_ok, swirl_ok] as ``readable``, dead (S,) bool no bump, no_swirl (S,) bool)."""
        marked = self.mark(sign, sign)
        usable, centre_ok, index_ok, swirl_ok = self.readable(marked, sign)
        dead, no_swirl = ~(usable | centre_ok | index_ok), ~swirl_ok
        if dead.any() or no_swirl.any():
            marked = self.mark(np.where(dead, 0.0, sign), np.where(dead | no_swirl, 0.0, sign))
            usable, centre_ok, index_ok, swirl_ok = (f & ~dead for f in self.readable(marked, sign))
            swirl_ok &= ~no_swirl
        return marked, [usable, centre_ok, index_ok, swirl_ok], dead, no_swirl

    def protected(self, keep: np.ndarray) -> np.ndarray:
        """(n,) bool: the vertices the progressive mesh keeps to the end, the site vertex and its ring
        for the sites ``keep`` (S,) bool."""
        return protected_vertices(len(self.vertices), self.sites[keep], self.ring[keep])


@dataclasses.dataclass
class SitePlaces:
    """The first half of the analysis: the sites, their frames and samples, and the protected rings
    (S sites, K samples). It names the vertices the progressive mesh keeps (``protected``): ``embed``
    hands them to the build waiting for them, which then runs while the second half (``lay_out``)
    and the marking run.

    sites (S,) int64; normal, t1, t2 (S, 3) float64 the site frames; radius, amplitude, swirl: the
    bump radius and the bump and swirl amplitudes; sample_site, sample_vertex (K,) int64; u, v (K,)
    float64 each sample's tangent coordinates in its site's frame; normals (K, 3) float64 the
    samples' vertex normals; prof (K,) float64 the bump profile there; ring (S, RING) int64 as in
    ``SiteAnalysis``."""

    vertices: np.ndarray
    faces: np.ndarray
    adj: Adjacency
    sites: np.ndarray
    n_bits: int
    per_bit: int
    normal: np.ndarray
    t1: np.ndarray
    t2: np.ndarray
    radius: float
    amplitude: float
    swirl: float
    sample_site: np.ndarray
    sample_vertex: np.ndarray
    u: np.ndarray
    v: np.ndarray
    normals: np.ndarray
    prof: np.ndarray
    samples: Samples
    ring: np.ndarray

    def protected(self) -> np.ndarray:
        """(n,) bool: every site vertex and its protected ring."""
        return protected_vertices(len(self.vertices), self.sites, self.ring)


def protected_vertices(n: int, sites: np.ndarray, ring: np.ndarray) -> np.ndarray:
    """(n,) bool: the vertices the progressive mesh keeps to the end, the ``sites`` (S,) int64 and
    their rings (S, RING) int64 (-1: none found)."""
    protected = np.zeros(n, bool)
    protected[sites] = True
    protected[ring[ring >= 0]] = True
    return protected


def analyse(
    V: np.ndarray,
    F: np.ndarray,
    secret: str,
    strength: float,
    n_bits: int,
    sites_per_bit: int = SITES_PER_BIT,
    radius_edges: float = RADIUS_EDGES,
    report: Callable[[float, str], None] = no_progress,
    adj: Optional[Adjacency] = None,
) -> SiteAnalysis:
    """The robust scheme's analysis of a mesh V (n, 3) float64, F (m, 3) int64 for the key's
    ``secret``: ``n_bits`` bits, ``sites_per_bit`` sites each (fewer on small meshes, down to 2);
    ``adj``: the mesh's adjacency, when the caller has it."""
    return lay_out(place_sites(V, F, secret, strength, n_bits, sites_per_bit, radius_edges, report, adj), secret)


def place_sites(
    V: np.ndarray,
    F: np.ndarray,
    secret: str,
    strength: float,
    n_bits: int,
    sites_per_bit: int = SITES_PER_BIT,
    radius_edges: float = RADIUS_EDGES,
    report: Callable[[float, str], None] = no_progress,
    adj: Optional[Adjacency] = None,
) -> SitePlaces:
    """The first half of ``analyse``: sites, frames, samples and protected rings (``adj``: the mesh's
    adjacency, when the caller has it)."""
    per_bit = max(2, 2 * (int(sites_per_bit) // 2))
    nb = n_bits
    report(0.0, "analysing the mesh")
    adj = build_adjacency(F, len(V)) if adj is None else adj
    cross = face_cross(V, F)  # the faces' cross products: their normals and the vertex normals
    eligible = eligible_carriers(V, adj, seed=derive_seed(secret, "som"), cross=cross)
    while True:  # fewer sites per bit on small meshes, down to 2
        try:
            sites = select_carriers(V, adj, eligible, nb * per_bit, seed=derive_seed(secret, "robust-sites"))
            break
        except PayloadError:
            if per_bit <= 2:
                raise
            per_bit -= 2
    report(0.1, f"{len(sites)} sites chosen")
    edge = mean_edge_length(V, adj)
    P = V[sites]
    # a site's samples (to OUTER r) must not reach another site's bump (r): r (1 + OUTER) below the
    # closest spacing. On small meshes they may overlap a little; a site whose own reading on the
    # marked mesh is not clearly its sign is then left out (``usable``).
    r = max(min(radius_edges * edge, 0.95 * min_spacing(P) / (1.0 + OUTER)), min(1.5, radius_edges) * edge)
    A = strength * AMPLITUDE_PER_STRENGTH * edge
    At = strength * SWIRL_PER_STRENGTH * edge

    vn = vertex_normals(V, F, cross)
    si, vi, d = pairs_within(P, V, np.full(len(P), OUTER * r))
    # site normal: mean vertex normal over the disc (same side as the site's own normal)
    disc = (np.einsum("ij,ij->i", vn[vi], vn[sites][si]) > 0.3) & (d < r)
    N = np.stack([np.bincount(si[disc], weights=vn[vi[disc], a], minlength=len(P)) for a in range(3)], 1)
    N /= np.maximum(np.linalg.norm(N, axis=1), 1e-300)[:, None]
    t1, t2 = tangent_frames(N)

    # samples: vertices near the site where the surface faces its way (a height field over the
    # tangent plane), in the site frame; stored as float32, and the profile computed from those
    rel = V[vi] - P[si]
    u = np.einsum("ij,ij->i", rel, t1[si]).astype(np.float32).astype(np.float64)
    v = np.einsum("ij,ij->i", rel, t2[si]).astype(np.float32).astype(np.float64)
    samp = (np.einsum("ij,ij->i", vn[vi], N[si]) > 0.5) & (np.hypot(u, v) < OUTER * r)
    si, vi, d, u, v = si[samp], vi[samp], d[samp], u[samp], v[samp]
    h_ref = np.einsum("ij,ij->i", V[vi] - P[si], N[si])
    normal_tt = np.stack([np.einsum("ij,ij->i", vn[vi], t1[si]), np.einsum("ij,ij->i", vn[vi], t2[si])], axis=1)
    normal_tt = normal_tt.astype(np.float16).astype(np.float64)  # as stored
    prof = profile(u, v, r)
    counts = np.bincount(si, minlength=len(P))
    samples = Samples(counts, u, v, h_ref, vi, normal_tt)
    normals = vn[vi]

    # protected annulus vertices: nearest to RING_DISTANCE * r at keyed angles, facing the site
    phi = np.arctan2(v, u)
    theta0 = np.random.default_rng(derive_seed(secret, "robust-angles")).uniform(0, 2 * np.pi, len(P))
    dt = np.hypot(u, v)
    ring_ok = (np.einsum("ij,ij->i", normals, N[si]) > 0.8) & (dt > 1.05 * r)
    ring = np.full((len(P), RING), -1, np.int64)
    # each site's samples are consecutive (pairs_within orders its pairs by site): its pick is its
    # first sample of least score
    new_site = np.r_[True, si[1:] != si[:-1]] if len(si) else np.zeros(0, bool)
    starts, group = np.flatnonzero(new_site), np.cumsum(new_site) - 1
    for k in range(RING):  # RING (3) iterations
        target = theta0 + 2 * np.pi * k / RING
        dphi = np.abs(np.angle(np.exp(1j * (phi - target[si]))))
        score = dphi + np.abs(dt / r - RING_DISTANCE)
        score[~ring_ok] = np.inf
        first = _first_least(score, starts, group)
        good = np.isfinite(score[first])
        ring[si[first][good], k] = vi[first][good]
    return SitePlaces(
        vertices=V,
        faces=F,
        adj=adj,
        sites=sites,
        n_bits=nb,
        per_bit=per_bit,
        normal=N,
        t1=t1,
        t2=t2,
        radius=r,
        amplitude=A,
        swirl=At,
        sample_site=si,
        sample_vertex=vi,
        u=u,
        v=v,
        normals=normals,
        prof=prof,
        samples=samples,
        ring=ring,
    )


def lay_out(places: SitePlaces, secret: str, attempt: int = 0, unread: Optional[np.ndarray] = None) -> SiteAnalysis:
    """The second half of ``analyse``: the keyed bit layout and chips, the bump and swirl fields.
    ``attempt`` > 0 draws another layout of the same sites from the secret (``selfcheck``); ``unread``
    (S,) bool: sites a registered copy did not read in an earlier attempt, so that the layout deals each
    bit some site that reads (``layout.assign_bits``)."""
    pl = places
    P, si, r, A, At = pl.vertices[pl.sites], pl.sample_site, pl.radius, pl.amplitude, pl.swirl
    # keyed bit assignment (even readable energy per bit) and chips
    tp, tg = index_templates(pl.samples, r, At / A)
    energy = A * A * (tp * tp).sum(axis=1) + At * At * (tg * tg).sum(axis=(1, 2))
    again = f":{attempt}" if attempt else ""  # (the first layout's labels are those of every earlier key)
    bit_of = assign_bits(P, pl.n_bits, pl.per_bit, derive_seed(secret, "robust-assign" + again), energy, unread)
    rng = np.random.default_rng(derive_seed(secret, "robust-chips" + again))
    order = np.lexsort((rng.random(len(P)), bit_of))  # each bit's sites in a keyed order
    rank = np.arange(len(P)) - np.searchsorted(bit_of[order], bit_of[order])
    chip = np.empty(len(P))
    chip[order] = np.where(rank % 2 == 0, 1.0, -1.0)  # balanced: a global bias cancels in a bit

    # the bumps, and the swirls in each vertex's own tangent plane (they move vertices, not the surface)
    gu, gv = swirl(pl.u, pl.v, r)
    e = gu[:, None] * pl.t1[si] + gv[:, None] * pl.t2[si]
    e -= np.einsum("ij,ij->i", e, pl.normals)[:, None] * pl.normals
    none = np.zeros(len(P), bool)
    site = RobustKeyData(
        bit=bit_of,
        chip=chip,
        usable=none,
        centre_ok=none,
        swirl_ok=none,
        index_ok=none,
        origin=P,
        normal=pl.normal,
        radius=r,
        amplitude=A,
        swirl=At,
        samples=pl.samples,
        frame=None,
    )
    return SiteAnalysis(
        vertices=pl.vertices,
        faces=pl.faces,
        adj=pl.adj,
        sites=pl.sites,
        site=site,
        n_bits=pl.n_bits,
        sample_site=si,
        sample_vertex=pl.sample_vertex,
        bump_field=(A * pl.prof)[:, None] * pl.normal[si],
        swirl_field=At * e,
        ring=pl.ring,
    )


def _first_least(score: np.ndarray, starts: np.ndarray, group: np.ndarray) -> np.ndarray:
    """For runs of consecutive entries (group (K,) int64 each entry's run, non-decreasing; starts the
    runs' first entries): the index of each run's first entry of least ``score`` (K,) float64."""
    if len(score) == 0:
        return starts
    least = np.flatnonzero(score == np.minimum.reduceat(score, starts)[group])
    return least[np.r_[True, group[least[1:]] != group[least[:-1]]]]


def _coded_sites(
    V, F, secret: str, strength: float, nb: int, sites_per_bit: int, radius_edges: float, report, adj: Adjacency
) -> tuple[SitePlaces, Optional[BCHCode]]:
    """The sites of a payload of ``nb`` bits and its code: the payload's BCH codeword (``code``) over about
    as many sites as the payload alone would get (``sites_per_bit`` per payload bit, an even number per
    coded bit); the payload alone, ``sites_per_bit`` each (fewer on small meshes), when the mesh cannot hold
    that many sites for the codeword (crowded sites spoil each other: the code would not pay) or no code fits."""
    code = payload_code(nb)
    if code is not None:
        per_coded = max(2, 2 * round(sites_per_bit * nb / code.n / 2))
        try:
            places = place_sites(V, F, secret, strength, code.n, per_coded, radius_edges, report, adj)
            if places.per_bit == per_coded:
                return places, code
        except PayloadError:
            pass
    return place_sites(V, F, secret, strength, nb, sites_per_bit, radius_edges, report, adj), None


def embed(
    vertices,
    faces,
    options: Optional[EmbedOptions] = None,
    progress: Progress = None,
    sites_per_bit: int = SITES_PER_BIT,
    radius_edges: float = RADIUS_EDGES,
) -> EmbedResult:
    """Watermark a mesh with the robust scheme (``pmwm.schemes.robust``); same options and result as
    ``pmwm.embed``. vertices : (n, 3) float64, faces : (m, 3) int64."""
    with loading_engine():  # the KD-tree's imports while the mesh is checked and its sites chosen
        return _embed(vertices, faces, options, progress, sites_per_bit, radius_edges)


def _embed(vertices, faces, options, progress, sites_per_bit, radius_edges) -> EmbedResult:
    job = start_embed(vertices, faces, options, progress, NAME, DEFAULT_STRENGTH)
    V, F, secret, bits, report = job.vertices, job.faces, job.secret, job.bits, job.report
    nb = len(bits)
    adj = build_adjacency(F, len(V))
    base = base_vertex_count(job.options.base_ratio, len(V))
    # the progressive mesh of the unmarked mesh, every site protected, built beside the analysis and
    # the marking (its set-up runs while the sites are placed; it waits for them before its first
    # pass); the marked positions go in after. None built when the options ask for none.
    protect = Later()
    build = job.options.progressive
    with beside(build, build_progressive_mesh, V, F, base_vertices=base, protected=protect, adjacency=adj) as building:
        places, code = _coded_sites(V, F, secret, job.strength, nb, sites_per_bit, radius_edges, report, adj)
        if build:  # (the vertices to protect only when something is built)
            protect.set(places.protected())
        coded = coded_bits(bits, code)
        w = coded ^ keyed_bits(secret, "scramble", len(coded))

        def mark(attempt: int, unread: Optional[np.ndarray]) -> selfcheck.Marking:
            an = lay_out(places, secret, attempt, unread)
            site = an.site
            sign = site.chip * np.where(w[site.bit] == 1, 1.0, -1.0)
            marked, (usable, centre_ok, index_ok, swirl_ok), _, _ = an.mark_readable(sign)
            frame = surface_frame(marked, F, REF_POINTS, derive_seed(secret, "robust-frame") % (2**31))
            first_site = np.array([np.flatnonzero(site.bit == b)[0] for b in range(nb)])
            data = dataclasses.replace(
                site, usable=usable, centre_ok=centre_ok, swirl_ok=swirl_ok, index_ok=index_ok, frame=frame, code=code
            )
            # the key read back from its stored form, so that it reads exactly as the key file will
            key_of = mesh_key(
                job, NAME, marked, adj, an.sites[first_site], data=RobustKeyData.from_extra(data.to_extra(), nb, len(V))
            )
            return selfcheck.Marking(marked, key_of, ~usable)

        report(0.2, "marking the sites and reading them back")  # (else another layout, or a PayloadError)
        marking = selfcheck.ensure(
            mark, F, verify, _payload_words(job), _advice(job), lambda message: report(0.2, message)
        )
        marked = marking.vertices

        def marked_pm() -> ProgressiveMesh:  # awaited last: the key's other fields are made meanwhile
            pm, _ = building.result(lambda f, msg: report(0.25 + 0.7 * f, msg))
            return with_positions(pm, marked)

        return finish_embed(job, marked, marked_pm if build else None, places.sites, marking.key_of)


def _payload_words(job) -> str:
    """The payload's size in words, for a refusal: "a 9-byte payload" or "a 64-bit payload"."""
    if job.payload_kind == "text" and job.options.payload is not None:
        return f"a {len(job.options.payload.encode('utf-8'))}-byte payload"
    return f"a {len(job.bits)}-bit payload"


def _advice(job) -> str:
    """What to try when the mark does not read back: a higher strength when it was set below the default, a
    shorter payload, a finer mesh."""
    weak = f"a higher --strength ({DEFAULT_STRENGTH:g} by default), " if job.strength < DEFAULT_STRENGTH else ""
    return f"{weak}a shorter payload, or a mesh with more vertices (subdivide it)"
