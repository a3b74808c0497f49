"""Types and steps every scheme shares: options, result, verdict, payload bits, the decision, the
scheme interface.

Below the schemes (``pmwm.schemes.*`` import this module, never the reverse). The keyed
pseudo-random streams every scheme draws from are ``WatermarkKey.stream`` and ``derive_seed``
(``pmwm.key``).

Keying. A scheme is read either with a key file (``KEY_FILE``: the embed returns a ``WatermarkKey``
that the owner keeps) or with a pass phrase alone (``PASS_PHRASE``: the embed takes it in
``EmbedOptions.passphrase`` and returns no key); ``Scheme.keying`` says which.

Verdict. A scheme reads one score per payload bit (sign = the scrambled bit, 0 = an erasure). An
erasure gets a keyed coin flip, so that with K of N bits matching, p = P(Binomial(N, 1/2) >= K) is
the exact false-positive probability of an unmarked mesh or a wrong key; the mesh is ``marked``
when p < p_threshold (1e-6 by default). The payload is *confirmed* only when the scheme can vouch
for every bit of it (``confirm_payload``); a verdict shows the payload (``Verdict.payload``, the
JSON's "payload" and "bits") only then. How the scheme read the mark is its ``VerdictDetail``; the
verdict in words is ``pmwm.wording``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, ClassVar, Optional, Sequence, Union

import numpy as np

from . import metrics
from .errors import PayloadError
from .adjacency import Adjacency
from .features import mean_edge_length
from .key import WatermarkKey, derive_seed, face_fingerprint, make_secret
from .progressive import ProgressiveMesh
from .validate import MAX_COORDINATE, check_mesh, parse_bits

__all__ = [
    "Progress",
    "DEFAULT_BITS",
    "KEY_FILE",
    "PASS_PHRASE",
    "EmbedOptions",
    "EmbedResult",
    "Verdict",
    "KeysVerdict",
    "VerdictDetail",
    "payload_bits",
    "decode_text",
    "check_options",
    "confirm_payload",
    "verdict_from_scores",
    "no_progress",
    "Scheme",
    "EmbedJob",
    "start_embed",
    "finish_embed",
    "mesh_key",
]

Progress = Optional[Callable[[float, str], None]]
DEFAULT_BITS = 64
KEY_FILE = "key file"  # ``Scheme.keying``: the embed returns a WatermarkKey, the reader needs it
PASS_PHRASE = "pass phrase"  # ``Scheme.keying``: marked and read with a pass phrase alone, no key


def no_progress(fraction: float, message: str) -> None:
    """The progress callback used when none is given."""


@dataclass
class EmbedOptions:
    """Options of ``pmwm.embed`` (see docs/api.md).

    scheme: "robust" (the default), "paper" (the paper's Algorithms 1-2), "cho1" or "cho2" (Cho et
    al. 2007, methods I and II), "blind" (read with ``passphrase`` alone). strength: None for the
    scheme's default; for robust and paper a factor (2), for cho1/cho2 Cho's margin alpha (0.05),
    for blind the bin-mean margin (0.07). passphrase: the secret of a scheme keyed by a pass phrase
    (``Scheme.keying == PASS_PHRASE``; never stored).
    progressive: build the progressive mesh (``EmbedResult.pm``); False when it will not be shipped
    (``pmwm embed`` without ``--pm``): robust, blind, cho1 and cho2 then skip the build, most of an
    embed's time, and give the same marked mesh with ``pm`` None (the key records the mesh's own
    numbering as its progressive one); the paper scheme builds it anyway (its bits go in during the
    collapses).
    """

    payload: Optional[str] = None
    bits: Optional[Union[str, Sequence[int]]] = None
    n_bits: int = DEFAULT_BITS
    strength: Optional[float] = None
    base_ratio: float = 0.03
    seed: Optional[int] = None
    scheme: str = "robust"
    passphrase: Optional[str] = field(default=None, repr=False)
    progressive: bool = True


@dataclass
class EmbedResult:
    """The marked mesh, its progressive mesh (None when ``EmbedOptions.progressive`` was False) and the key.

    vertices : (n, 3) float64 marked positions (float32-exact), in the input's vertex order.
    faces : (m, 3) int64, the input's. key: what the reader needs, for a scheme keyed by a key file;
    None for one keyed by a pass phrase (the pass phrase is all the reader needs). carriers : (k,)
    int64 vertices that carry the mark (robust: sites; Cho, blind: none, the mark is global). bits :
    (N,) uint8 payload bits. strength: the strength used (the option's, the scheme's default, or the
    one the scheme calibrated for this mesh).
    """

    vertices: np.ndarray
    faces: np.ndarray
    pm: Optional[ProgressiveMesh]
    key: Optional[WatermarkKey]
    carriers: np.ndarray
    bits: np.ndarray
    vsnr_db: float
    rmse: float
    strength: float = float("nan")
    notes: tuple[str, ...] = ()  # what the user should know of this marking (the command line prints them)


@dataclass(frozen=True)
class VerdictDetail:
    """How a scheme read a verdict, beyond the fields every verdict has: each scheme returns its own
    dataclass (robust, paper, Cho, blind), able to say itself in plain words (``in_words``) and give
    its numbers (``numbers``); ``pmwm.wording`` puts them into the verdict's text. This base class is
    the detail of a verdict that says nothing more (built by hand)."""

    counted: ClassVar[str] = "bits"  # what ``Verdict.matches`` counts, in words

    def headline_note(self, verdict: "Verdict") -> str:
        """The end of the verdict's first line (after the p-value): how much of the mark was read."""
        v = verdict
        return f"correlation {v.correlation:.3f}, {v.carriers_found}/{v.carriers_total} carriers read ({v.mode})"

    def notes(self) -> list[str]:
        """Sentences a reader of the verdict must see beside it (the command line prints them under its
        first line): none unless the reading departs from the suspect as given."""
        return []

    def in_words(self) -> list[tuple[str, str]]:
        """(label, plain sentence) rows on how the mark was read, for a table a non-specialist reads."""
        return []

    def numbers(self) -> list[tuple[str, str]]:
        """(name, value) rows of the reading's figures, for a technical section."""
        return []


@dataclass
class Verdict:
    """The answer of ``pmwm.verify``.

    bits: the payload bits read ("0110..."): a key-file scheme gives every bit as read, to compare
    with the key's (``bit_errors``), confirmed or not; a pass-phrase scheme gives them only when the
    payload is confirmed ("" otherwise). payload: the text payload, only when confirmed.
    payload_confirmed: every payload bit is vouched for (``confirm_payload``, or the scheme's own
    check). detail: how the scheme read it (``VerdictDetail``).
    """

    marked: bool
    p_value: float
    bits: str
    payload: Optional[str]
    matches: int
    bit_errors: int
    correlation: float
    carriers_found: int
    carriers_total: int
    mode: str
    p_threshold: float = 1e-6
    payload_confirmed: bool = False
    detail: VerdictDetail = field(default_factory=VerdictDetail)
    # What the verdict was read from (for reports; not in to_dict): scores (N,) float64, one soft
    # score per bit as read (sign = the scrambled bit, magnitude = confidence, 0 = erasure);
    # places (k, 3) float64, where the mark was read, in the suspect's coordinates (robust: the
    # sites read; paper: the carriers found; Cho: none, the mark is global), place_bits (k,) int64
    # the bit each place carries.
    scores: Optional[np.ndarray] = None
    places: Optional[np.ndarray] = None
    place_bits: Optional[np.ndarray] = None

    def to_dict(self) -> dict:
        """The verdict as JSON-ready data (``pmwm verify --json``): "bits" and "payload" are null unless
        the payload is confirmed."""
        return {
            "marked": self.marked,
            "p_value": self.p_value,
            "p_threshold": self.p_threshold,
            "payload_confirmed": self.payload_confirmed,
            "bits": self.bits if self.payload_confirmed else None,
            "payload": self.payload if self.payload_confirmed else None,
            "matches": self.matches,
            "bit_errors": self.bit_errors,
            "correlation": self.correlation,
            "carriers_found": self.carriers_found,
            "carriers_total": self.carriers_total,
            "mode": self.mode,
        }


@dataclass
class KeysVerdict:
    """The answer of ``pmwm.verify_keys``: one suspect read with several keys, one verdict per key in the
    keys' order.

    Each verdict is the key's own (``pmwm.verify``'s), with its p-value multiplied by the number of keys
    tried (``tried``; Bonferroni, ``metrics.union_bound``): the chance that any of them reads a mark by
    chance stays below the threshold. A verdict is marked, and shows its payload, only after that
    correction; ``p_single`` (one per key) is each key's p-value before it. Several marked keys mean
    several marks on one copy (see docs/dispute.md for what settles who marked it first).
    """

    verdicts: list[Verdict]
    p_single: list[float]

    @property
    def tried(self) -> int:
        """The number of keys read."""
        return len(self.verdicts)

    @property
    def marked_keys(self) -> list[int]:
        """The indices of the keys whose mark the suspect carries (after the correction)."""
        return [i for i, v in enumerate(self.verdicts) if v.marked]

    def to_dict(self, names: Sequence[str]) -> dict:
        """JSON-ready data (``pmwm verify --key A --key B --json``): the keys tried, how many read marked,
        the correction, and each key's verdict (``Verdict.to_dict``) under its name (``names``, one per
        key) with its p-value before the correction."""
        return {
            "keys_tried": self.tried,
            "keys_marked": len(self.marked_keys),
            "correction": f"each p_value is the key's own times {self.tried}, the keys tried (Bonferroni)",
            "verdicts": [
                {"key": str(name), **v.to_dict(), "p_value_single_key": p}
                for name, v, p in zip(names, self.verdicts, self.p_single)
            ],
        }


# --------------------------------------------------------------------------- payload bits


def payload_bits(options: EmbedOptions, secret: str) -> tuple[np.ndarray, str]:
    """The payload as (N,) uint8 bits and its kind: text (UTF-8, padded to at least 64 bits),
    explicit bits, or random (drawn from the key's secret)."""
    if options.payload is not None and options.bits is not None:
        raise PayloadError("give a text payload or explicit bits, not both")
    if options.payload is not None:
        data = options.payload.encode("utf-8")
        if not data:
            raise PayloadError("the payload text is empty; give some text or use --bits")
        data = data + b"\0" * max(0, DEFAULT_BITS // 8 - len(data))
        return np.unpackbits(np.frombuffer(data, np.uint8)), "text"
    if options.bits is not None:
        return parse_bits(options.bits), "bits"
    if options.n_bits < 1:
        raise PayloadError("the number of bits must be at least 1")
    rng = np.random.default_rng(derive_seed(secret, "random-payload"))
    return rng.integers(0, 2, options.n_bits).astype(np.uint8), "random"


def decode_text(bits: np.ndarray) -> Optional[str]:
    """Text payload from bits (trailing NUL bytes dropped); None if not valid UTF-8."""
    if len(bits) % 8:
        return None
    data = np.packbits(np.asarray(bits, np.uint8)).tobytes().rstrip(b"\0")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return None


def check_options(opts: EmbedOptions, default_strength: float) -> float:
    """The strength to use (``opts.strength`` or the scheme's default) when the options make sense,
    else a PayloadError."""
    strength = default_strength if opts.strength is None else opts.strength
    if not (isinstance(strength, (int, float, np.floating)) and strength > 0 and np.isfinite(strength)):
        raise PayloadError(f"strength must be a positive number, got {strength}")
    if not (0 < opts.base_ratio <= 1):
        raise PayloadError(f"base ratio must be in (0, 1], got {opts.base_ratio}")
    return float(strength)


# --------------------------------------------------------------------------- the steps of every embedder


@dataclass
class EmbedJob:
    """What every embedder starts from: the checked options and mesh, the key's secret (from the
    seed, or fresh) and the payload bits. vertices : (n, 3) float64, faces : (m, 3) int64."""

    options: EmbedOptions
    strength: float
    vertices: np.ndarray
    faces: np.ndarray
    secret: str
    bits: np.ndarray
    payload_kind: str
    report: Callable[[float, str], None]


def start_embed(
    vertices, faces, options: Optional[EmbedOptions], progress: Progress, scheme: str, default_strength: float
) -> EmbedJob:
    """Check the options and the mesh, draw the secret and the payload: the first steps of every
    scheme's embedder (a PayloadError or MeshError naming what is wrong)."""
    opts = options or EmbedOptions(scheme=scheme)
    strength = check_options(opts, default_strength)
    V, F = check_mesh(vertices, faces, max_coordinate=MAX_COORDINATE)
    secret = make_secret(opts.seed)
    bits, kind = payload_bits(opts, secret)
    return EmbedJob(opts, strength, V, F, secret, bits, kind, progress or no_progress)


def make_key(
    secret: str,
    bits: np.ndarray,
    payload_kind: str,
    strength: float,
    vertices: np.ndarray,
    faces: np.ndarray,
    marked: np.ndarray,
    adj: Adjacency,
    pm: Optional[ProgressiveMesh],
    key_carriers: np.ndarray,
    scheme: str,
    data: object = None,
) -> WatermarkKey:
    """The key of a marked mesh: vertices (n, 3) the input, faces (m, 3), marked (n, 3) the marked
    positions, ``key_carriers`` (k,) int64 the vertices the key records (index, progressive-mesh
    index and marked place), the mesh's size and the faces fingerprints in both numberings, and the
    scheme's typed data (written to the key file's ``extra`` by its ``to_extra``)."""
    return WatermarkKey(
        **_key_fields(secret, bits, payload_kind, strength, vertices, faces, marked, adj, key_carriers, scheme, data),
        **_pm_fields(pm, faces, key_carriers),
    )


def _key_fields(secret, bits, payload_kind, strength, vertices, faces, marked, adj, key_carriers, scheme, data) -> dict:
    """``make_key``'s fields but those of the progressive mesh's numbering (``_pm_fields``)."""
    return dict(
        secret=secret,
        bits=bits,
        payload_kind=payload_kind,
        strength=strength,
        carrier_index=key_carriers,
        carrier_position=marked[key_carriers].copy(),
        n_vertices=len(vertices),
        n_faces=len(faces),
        mean_edge=mean_edge_length(marked, adj),
        bbox_diagonal=metrics.bbox_diagonal(vertices),
        scheme=scheme,
        data=data,
        faces_fingerprint=face_fingerprint(faces),
    )


def _pm_fields(pm: Optional[ProgressiveMesh], faces: np.ndarray, key_carriers: np.ndarray) -> dict:
    """The key's fields from the progressive mesh: the carriers' and the faces' progressive numbering
    (without one: the mesh's own numbering, and no faces fingerprint to match)."""
    if pm is None:
        return dict(carrier_pm_index=key_carriers.copy(), pm_faces_fingerprint="")
    pm_of = np.empty(len(pm.vertex_order), np.int64)
    pm_of[pm.vertex_order] = np.arange(len(pm.vertex_order))
    return dict(carrier_pm_index=pm_of[key_carriers], pm_faces_fingerprint=face_fingerprint(pm_of[faces]))


KeyOf = Callable[[Optional[ProgressiveMesh]], WatermarkKey]  # a key made from the progressive mesh (None: none)


def mesh_key(
    job: EmbedJob, scheme: str, marked: np.ndarray, adj: Adjacency, key_carriers: np.ndarray, data: object = None
) -> KeyOf:
    """The key of a scheme whose key records the mesh (robust, paper, Cho: ``make_key``), as a function of
    the progressive mesh: the fields of the mesh made now (while a build may still run), those of the
    progressive mesh's numbering when it is given. marked : (n, 3) float64 the marked mesh; key_carriers
    : (k,) int64 the vertices the key records (k = 0 or one per bit); data: the scheme's typed key data."""
    F = job.faces
    fields = _key_fields(
        job.secret, job.bits, job.payload_kind, job.strength, job.vertices, F, marked, adj, key_carriers, scheme, data
    )
    return lambda pm: WatermarkKey(**fields, **_pm_fields(pm, F, key_carriers))


def finish_embed(
    job: EmbedJob,
    marked: np.ndarray,
    pm: Union[None, ProgressiveMesh, Callable[[], ProgressiveMesh]],
    carriers: np.ndarray,
    key: Union[None, WatermarkKey, KeyOf],
) -> EmbedResult:
    """The result, the last step of every embedder. marked : (n, 3) float64 the marked mesh; carriers :
    the vertices reported as carrying the mark; ``pm``: the progressive mesh, None when none was built,
    or a callable giving it (a build still running in another thread: everything else is done before
    it is called); ``key``: the key, a function of the progressive mesh making it (``mesh_key``), or
    None (a scheme keyed by a pass phrase)."""
    V = job.vertices
    vsnr_db, rmse = metrics.vsnr(V, marked), metrics.vertex_rmse(V, marked)
    pm = pm() if callable(pm) else pm
    key = key(pm) if callable(key) else key
    job.report(1.0, "done")
    return EmbedResult(
        vertices=marked,
        faces=job.faces,
        pm=pm,
        key=key,
        carriers=carriers,
        bits=job.bits,
        vsnr_db=vsnr_db,
        rmse=rmse,
        strength=float(job.strength),
    )


# --------------------------------------------------------------------------- the decision


def confirm_payload(marked: bool, bits: np.ndarray, key: WatermarkKey) -> bool:
    """The rule of a key-file scheme: the payload is confirmed when the mesh is marked and every payload
    bit read, bits : (N,) uint8, is the key's. A scheme that corrects errors passes its own rule to
    ``verdict_from_scores`` (confirmed after the correction)."""
    return bool(marked and len(bits) == key.n_bits and np.array_equal(bits, key.bits))


def verdict_from_scores(
    score: np.ndarray,
    key: WatermarkKey,
    mode: str,
    p_threshold: float,
    detail: Optional[VerdictDetail] = None,
    confirm: Callable[[bool, np.ndarray, WatermarkKey], bool] = confirm_payload,
) -> Verdict:
    """The verdict from one score per bit, score : (N,) float64 (sign = scrambled bit, 0 = erasure); the
    payload text only when ``confirm(marked, bits read, key)`` holds; ``detail``: how the scheme read it."""
    n = key.n_bits
    erased = score == 0
    w = (score > 0).astype(np.uint8)
    coin = key.stream("erasure", n)
    w[erased] = coin[erased]
    bits = w ^ key.stream("scramble", n)
    matches = int(np.sum(bits == key.bits))
    p = metrics.binomial_tail(matches, n)
    marked = bool(p < p_threshold)
    confirmed = bool(confirm(marked, bits, key))
    payload = decode_text(bits) if key.payload_kind == "text" and confirmed else None
    return Verdict(
        marked=marked,
        p_value=float(p),
        bits="".join(map(str, bits.tolist())),
        payload=payload,
        matches=matches,
        bit_errors=n - matches,
        correlation=float(metrics.correlation(key.bits, bits)),
        carriers_found=int(np.sum(~erased)),
        carriers_total=n,
        mode=mode,
        p_threshold=p_threshold,
        payload_confirmed=confirmed,
        detail=VerdictDetail() if detail is None else detail,
        scores=np.asarray(score, np.float64).copy(),
        places=np.zeros((0, 3)),
        place_bits=np.zeros(0, np.int64),
    )


# --------------------------------------------------------------------------- the scheme interface


@dataclass(frozen=True)
class Scheme:
    """One watermarking scheme behind ``pmwm.embed`` / ``pmwm.verify`` (``pmwm.schemes.SCHEMES``).

    keying: ``KEY_FILE`` or ``PASS_PHRASE``, what the reader needs. embed(vertices, faces, options,
    progress) -> EmbedResult (a pass-phrase scheme takes it in ``options.passphrase`` and returns no
    key); verify(vertices, faces, secret, p_threshold, progress=None) -> Verdict, ``secret`` the WatermarkKey
    of a key-file scheme or the pass phrase (str) of a pass-phrase one, ``progress(fraction, message)``
    called at the reader's stages and last with 1.0; load_key_data(key) -> the scheme's
    typed key data (validated; a KeyFileError when damaged, or for a scheme that has no key file),
    called when a key file is read, before any suspect is loaded.
    """

    name: str
    default_strength: float
    embed: Callable[..., EmbedResult]
    verify: Callable[..., Verdict]
    load_key_data: Callable[[WatermarkKey], object]
    description: str = ""
    keying: str = KEY_FILE
