"""The robust watermarking scheme on the progressive mesh (``scheme="robust"``, the default).

Why. The paper's scheme reads each bit from one vertex against its 1-ring: any change of
connectivity (simplification, subdivision, re-export that re-orders) or a rotation loses it, and
noise of a fraction of an edge length flips it. Here every bit is spread over several *sites*, each
a smooth bump along the surface normal, read with a matched filter after registering the suspect to
the marked mesh.

Embedding.
- Payload code: the payload's bits go through a shortened BCH code correcting 4 errors (``code``; 92 coded
  bits for 64), and the sites carry the coded bits, about as many sites in all as the payload alone would
  get (an even number per coded bit). The key names the code (key format 3); a mesh too small for the
  codeword's sites carries the payload alone (format 2, as keys written before the code).
- Sites: SOM-suitable vertices (``pmwm.carriers``) picked by seeded farthest-point sampling,
  ``sites_per_bit`` per payload bit, assigned to bits so that each bit's sites are spread around the
  shape (pairs of roughly opposite sites, then keyed swaps checked against 512 plane cuts): a plane
  cutting off half the mesh leaves every bit a site. Vertex density varies over a scan, and with it
  the energy a site carries; pairs are dealt richest first in a snake order of the bits, and swaps
  that keep the cuts even the bits out (a bit's error rate is convex in its energy).
- Each site c with unit normal n (averaged over its disc) and tangent frame (t1, t2) gets a bump:
  vertex v whose tangent-plane distance d to c is below r moves by s * A * p(d) * n, with the
  profile p(d) = (1 - (d/r)^2)^2 and s = +-1 its chip (keyed, balanced within the bit) times the bit
  sign (payload XOR keyed sequence). r is ``RADIUS_EDGES`` mean edge lengths; A is ``strength`` *
  ``AMPLITUDE_PER_STRENGTH`` mean edge lengths.
- Swirl: the same vertices also turn about the site, each within its own tangent plane, by
  s * At * w(u, v) (w = the profile times (-v, u) / r, scaled to peak at 1; At is ``strength`` *
  ``SWIRL_PER_STRENGTH`` mean edge lengths). It moves vertices along the surface, not the surface, so
  surface distance (MRMS) barely sees it, while a copy that keeps the vertex order gives it back to
  the reader: at equal MRMS, the energy a noise attack has to drown is tripled.
- Samples: every vertex within ``OUTER`` * r of the site that faces the site's way. The key stores
  each sample's tangent coordinates (u, v), its height along n on the UNMARKED mesh, its vertex
  index and its vertex normal in the site frame (float16; the reader rebuilds from it what marking
  did to each vertex); the annulus samples (p = 0) let the reader remove a local offset and tilt.
- A site whose own readings of the marked mesh all miss its sign (a neighbour's bump on a small or
  unevenly meshed surface) is not marked at all, nor a swirl that does not read: no distortion is
  spent where no reading will look.
- The site vertex and ``RING`` annulus vertices at keyed angles are protected in the progressive
  mesh, so every level of detail, from the base mesh up, keeps each bump's peak and its surroundings.
- Read back (``selfcheck``): the embed reads its output with the key it returns, as written, re-posed and
  re-ordered, and with a little noise; a layout that does not read, MARKED with the payload confirmed and
  every bit with margin, is dealt again from the secret; none confirmed: a PayloadError, nothing returned.

Reading (on the suspect registered to the key's frame, ``pmwm.register``).
- Pose: a copy that is not in the key's frame and not in the marked vertex order is registered in every
  plausible pose, mirror images included (``pmwm.register.register_poses``): a symmetric shape fits its
  surface equally well in several. Each pose is screened on a third of the sites, the strongest are read in
  full, and the reading of smallest p-value is kept; its p-value is multiplied by the most poses the reader
  may try (``read.pose_bound``, a union bound). A mirror image says so (``mirrored`` in the verdict's
  details).
- Heights along n: by vertex index when the suspect has the marked mesh's vertices in the marked
  order (noise, smoothing and quantization keep it); otherwise where the line through each sample
  (u, v) crosses the suspect surface (any order, resolution or re-triangulation).
- Per site, y = height - stored height is modelled as a * p + offset + tilt + noise; a is estimated
  by the matched filter of p made orthogonal to (1, u, v), ridge-regularised by the site's own noise
  level: at low noise the offset and tilt (registration error, smoothing shrinkage) are removed
  exactly, at high noise the filter tends to p itself, the optimum for white noise. By vertex index,
  what Laplacian smoothing moved the unmarked surface by, vertex by vertex, is taken off first: the
  unmarked mesh's own uniform Laplacian and its powers at each sample vertex (``read.host_laplacians``:
  the key's places and the suspect's faces) with coefficients fitted once over all sites
  (``read.shared_fit``). a / A is the site's soft value (+-1 when intact).
- By vertex index, the suspect is registered by the similarity that fits the stored places of the
  sample vertices to the suspect's (thousands of known pairs; fitted in that direction because the
  stored places are noiseless, so heavy noise does not shrink the scale), and each site's swirl is
  read as well: the sample vertices' tangent-plane shifts (less the tangential part of what smoothing
  moved them by, fitted the same way) fitted as a * w' + a common shift, combined with the site's bump
  reading by inverse variance. w' and the height template p' are what marking moved each
  vertex: the embedder keeps the swirl off each vertex's own normal, so on a curved patch part of
  it runs along the site normal and is read with the bump. Every site whose reading by index was
  clean on the marked mesh is read, whether or not its protected ring was found.
- A copy that sits exactly in the key's frame (the marked mesh, any of its levels of detail, a lossless
  re-export) is read at each protected site vertex alone, exact at every level; where a neighbour's bump
  spoilt that reading on the marked mesh (small meshes), all samples are read instead, and so are the sites
  read by index of a copy that also keeps the marked vertex order (the site vertex alone cannot tell its own
  bump from another mark's on it).
- A bit is the sign of the sum of its sites' chip-signed log-likelihood ratios (``read.site_llr``): a site
  reads its sign times a gain in [0, 1.2] plus its noise, or, with a small prior probability, anything (a
  bump of another key's mark on or near it). Where the noise explains a reading, the site weighs as its
  inverse variance says (a site in a damaged or cropped region weighs little); a reading neither sign
  explains weighs nothing, and no site outweighs a few others. A bit with no readable site is an erasure
  and gets a keyed coin flip, so the binomial p-value of ``pmwm.base.verdict_from_scores`` (over the coded
  bits) stays exact: the ratio is odd in the reading.
- The payload is confirmed (``confirm``) when the key's codeword passes the generalised minimum
  distance test on the soft scores: no other codeword can pass it, so a confirmed payload is the one a
  decoder would give. The verdict shows the payload only when it is confirmed.

Not blind in the strict sense: the key holds, per sample, its place and its height on the unmarked
surface (never the faces), and 3,000 samples of the marked surface for registration.

Modules: ``fields`` (site frame, bump and swirl fields, templates, line-surface crossings),
``layout`` (the keyed bit assignment), ``code`` (the payload code and its confirmation), ``keydata`` (the typed
key data, its reader and writer),
``embed``, ``read``, ``selfcheck`` (the embed reads its own output back).
"""

from __future__ import annotations

from ...base import Scheme
from ...key import WatermarkKey
from .embed import DEFAULT_STRENGTH, embed
from .keydata import RobustKeyData
from .read import NAME, RobustDetail, confirm, key_data, read_scores, verify

__all__ = ["SCHEME", "embed", "verify", "read_scores", "key_data", "confirm", "RobustKeyData", "RobustDetail"]


def load_key_data(key: WatermarkKey) -> RobustKeyData:
    """The robust data of a key just read (checked; a KeyFileError when damaged)."""
    return RobustKeyData.from_extra(key.extra, key.n_bits, key.n_vertices)


SCHEME = Scheme(
    NAME,
    DEFAULT_STRENGTH,
    embed,
    verify,
    load_key_data,
    "bumps and swirls spread over sites, read after registration with a matched filter (default)",
)
