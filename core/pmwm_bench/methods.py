"""The methods compared, all behind pmwm's public interface: ``pmwm.embed`` / ``pmwm.verify``.

One class serves the four schemes; the scheme name selects the method and the display name is the
one the tables of the benchmark report use:

=========  ============  ==================================================
scheme     display name  what ``strength`` means
=========  ============  ==================================================
robust     pmwm          bump height factor (2: 0.24 mean edge lengths)
paper      pmwm-paper    the paper's factor (mu +- strength * sigma)
cho1       Cho I         Cho et al. 2007's alpha (margin of the bin mean)
cho2       Cho II        Cho et al. 2007's alpha (margin of the bin moment)
blind      pmwm-blind    the margin of the bin mean (Cho's method I on a quantile range)
=========  ============  ==================================================

The blind method marks with the pass phrase ``BLIND_PASSPHRASE`` + the seed and reads with it alone
(``extract`` returns the payload read, so its length is the payload's: 32, 64, 96 or 224 bits; the
benchmark protocol's 64 bits in total are 32 payload + 32 check bits, see benchmarks/bench_blind.py).

``strength=None`` leaves the choice to the scheme: its ``default_strength`` in ``pmwm.SCHEMES``
(2 for robust and paper, 0.05 for Cho's methods).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Optional

import numpy as np

import pmwm

#: scheme name (``pmwm.EmbedOptions.scheme``) -> display name in every table
DISPLAY: dict[str, str] = {
    "robust": "pmwm",
    "paper": "pmwm-paper",
    "cho1": "Cho I",
    "cho2": "Cho II",
    "blind": "pmwm-blind",
}
#: what each scheme's strength is, in a few words (for the reports)
STRENGTH_MEANING: dict[str, str] = {
    "robust": "bump height factor",
    "paper": "the paper's factor",
    "cho1": "alpha",
    "cho2": "alpha",
    "blind": "bin-mean margin",
}
#: the pass phrase of the blind method's embeddings (+ ":" + the seed)
BLIND_PASSPHRASE = "pmwm-bench"
#: the schemes that are pmwm's own (the paper protocol's Table 1 measures these only)
PMWM_SCHEMES: tuple[str, ...] = ("robust", "paper")
#: what ``pmwm bench`` runs by default (the blind method is run by benchmarks/bench_blind.py: its payload
#: lengths are 32, 64, 96 or 224 bits, not the paper protocol's 50)
ALL_SCHEMES: tuple[str, ...] = tuple(s for s in DISPLAY if s != "blind")
#: what ``pmwm bench --sweep`` runs by default: every scheme, the blind one too (its 64-bit payload is
#: followed by its 32 check bits; BER over the payload, a reading of another length counts as chance)
SWEEP_SCHEMES: tuple[str, ...] = tuple(DISPLAY)

_ALIASES = {
    "pmwm": "robust",
    "pmwm-robust": "robust",
    "pmwm-paper": "paper",
    "cho i": "cho1",
    "cho-i": "cho1",
    "choi": "cho1",
    "pmwm-blind": "blind",
    "cho ii": "cho2",
    "cho-ii": "cho2",
    "choii": "cho2",
    "cho-1": "cho1",
    "cho-2": "cho2",
}


def scheme_of(name: str) -> str:
    """The scheme name of a scheme or display name ("robust", "pmwm", "Cho II", "cho-ii", "cho2", ...)."""
    key = str(name).strip().lower()
    key = _ALIASES.get(key, key)
    if key not in DISPLAY:
        raise ValueError(f"unknown method {name!r}; use one of {', '.join(DISPLAY)}")
    return key


@dataclass(frozen=True)
class SchemeMethod:
    """One watermarking method of pmwm (``scheme``) at ``strength`` (None: the scheme's default).

    ``embed(V, F, bits, seed) -> (marked vertices (n, 3), key)`` and ``extract(V, F, key) -> bits``
    (a '0'/'1' string) are the uniform interface the runner and the sweep drive.
    """

    scheme: str
    strength: Optional[float] = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "scheme", scheme_of(self.scheme))

    @property
    def name(self) -> str:
        """Display name (``DISPLAY``)."""
        return DISPLAY[self.scheme]

    @property
    def effective_strength(self) -> float:
        """The strength the scheme embeds with (its default when ``strength`` is None)."""
        return pmwm.SCHEMES[self.scheme].default_strength if self.strength is None else float(self.strength)

    @property
    def is_pmwm(self) -> bool:
        """True for pmwm's own schemes (robust, paper), False for the Cho baselines."""
        return self.scheme in PMWM_SCHEMES

    def options(self, bits: Any, seed: Optional[int]) -> pmwm.EmbedOptions:
        """The ``pmwm.EmbedOptions`` of one embedding."""
        strength = None if self.strength is None else float(self.strength)
        phrase = f"{BLIND_PASSPHRASE}:{seed}" if pmwm.SCHEMES[self.scheme].keying == pmwm.PASS_PHRASE else None
        return pmwm.EmbedOptions(
            bits=np.asarray(bits).ravel(), seed=seed, strength=strength, scheme=self.scheme, passphrase=phrase
        )

    def embed(
        self, vertices: np.ndarray, faces: np.ndarray, bits: Any, seed: Optional[int] = None
    ) -> tuple[np.ndarray, Any]:
        """Mark (vertices (n, 3), faces (m, 3)) with ``bits`` ((b,) 0/1 or a '0'/'1' string), every random
        choice from ``seed``; returns (marked vertices (n, 3), what ``pmwm.verify`` reads with: the key, or
        the pass phrase (str) of a scheme keyed by one)."""
        opts = self.options(bits, seed)
        res = pmwm.embed(vertices, faces, opts)
        return res.vertices, res.key if res.key is not None else opts.passphrase

    def extract(self, vertices: np.ndarray, faces: np.ndarray, key: Any) -> str:
        """The bits read from a suspect copy (vertices (n', 3), faces (m', 3)), a '0'/'1' string ("" when a
        pass-phrase scheme reads no mark: it vouches for no bit)."""
        if isinstance(key, str):
            return pmwm.verify(vertices, faces, passphrase=key).bits
        return pmwm.verify(vertices, faces, key).bits


def default_methods(strength: Optional[float] = None) -> list[SchemeMethod]:
    """[pmwm (robust, at ``strength``; None: its default 2), pmwm-paper, Cho I, Cho II] at their defaults."""
    return [SchemeMethod("robust", strength), SchemeMethod("paper"), SchemeMethod("cho1"), SchemeMethod("cho2")]


__all__ = [
    "ALL_SCHEMES",
    "SWEEP_SCHEMES",
    "BLIND_PASSPHRASE",
    "DISPLAY",
    "PMWM_SCHEMES",
    "STRENGTH_MEANING",
    "SchemeMethod",
    "default_methods",
    "scheme_of",
]
