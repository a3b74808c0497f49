"""Published numbers the reports print beside ours: the paper's Tables 1-4 and Cho et al.'s BER.

The paper's tables are per paper model (bunny, dragon, venus; ``PAPER_MODELS`` gives the column
order). Noise and smoothing entries hold (proposed, Cho) per model; cropping holds the proposed
method only. ``CHO_PUBLISHED`` is Cho et al. 2007 on the LIRIS benchmark's Venus, 64 bits, MRMS
0.008 % (Wang, Lavoue, Denis, Baskurt 2010), keyed by (attack group, setting value).
"""

from __future__ import annotations

#: column order of every paper table
PAPER_MODELS: tuple[str, str, str] = ("bunny", "dragon", "venus")

PAPER_TABLE1: dict[str, tuple[float, float, float]] = {  # VSNR (dB) at M = 50, 80, 120
    "bunny": (104.40, 104.19, 103.98),
    "dragon": (113.95, 113.17, 112.19),
    "venus": (137.16, 136.24, 135.14),
}
PAPER_NOISE = {  # amplitude -> (ours per model, Cho per model)
    0.005: ((1.0, 0.95, 0.90), (0.28, 0.46, 0.41)),
    0.009: ((0.90, 0.75, 0.54), (0.17, 0.22, 0.15)),
    0.01: ((0.83, 0.56, 0.66), (0.16, 0.20, 0.06)),
    0.03: ((0.43, 0.31, 0.20), (0.14, 0.21, 0.19)),
    0.05: ((0.28, 0.28, 0.08), (0.12, 0.22, 0.15)),
}
PAPER_SMOOTH = {  # iterations -> (ours, Cho); the paper prints Cho/dragon/20 as "80", read as 0.80
    5: ((1.0, 0.954, 0.954), (1.0, 1.0, 0.95)),
    10: ((0.95, 0.80, 0.95), (0.90, 0.95, 0.84)),
    15: ((0.66, 0.546, 0.80), (0.90, 0.83, 0.83)),
    20: ((0.61, 0.54, 0.75), (0.85, 0.80, 0.87)),
}
PAPER_CROP = {3: (0.90, 0.85, 0.80), 5: (0.90, 0.75, 0.65), 10: (0.71, 0.546, 0.45), 20: (0.71, 0.36, 0.45)}
#: attack group of the paper protocol -> its published table
PAPER_TABLES = {"noise": PAPER_NOISE, "smoothing": PAPER_SMOOTH, "cropping": PAPER_CROP}

#: Cho et al. 2007 on the benchmark's Venus, 64 bits, MRMS 0.008 % (Wang et al. 2010): BER
CHO_PUBLISHED = {
    ("noise", 0.0005): 0.01,
    ("noise", 0.001): 0.03,
    ("noise", 0.003): 0.13,
    ("noise", 0.005): 0.28,
    ("smoothing", 5): 0.10,
    ("smoothing", 10): 0.23,
    ("smoothing", 30): 0.38,
    ("smoothing", 50): 0.45,
    ("quantization", 11): 0.0,
    ("quantization", 10): 0.04,
    ("quantization", 9): 0.14,
    ("quantization", 8): 0.26,
    ("quantization", 7): 0.46,
}


def paper_value(table: dict, key, paper_model: str, which: int) -> str:
    """The published cell of ``table`` at setting ``key`` for ``paper_model`` ("–" when there is none);
    ``which`` 0 = the paper's proposed method, 1 = its Cho column (ignored for one-column tables)."""
    if paper_model not in PAPER_MODELS or key not in table:
        return "–"
    entry = table[key]
    vals = entry[which] if isinstance(entry[0], tuple) else entry
    return f"{vals[PAPER_MODELS.index(paper_model)]:g}"


__all__ = [
    "CHO_PUBLISHED",
    "PAPER_CROP",
    "PAPER_MODELS",
    "PAPER_NOISE",
    "PAPER_SMOOTH",
    "PAPER_TABLE1",
    "PAPER_TABLES",
    "paper_value",
]
