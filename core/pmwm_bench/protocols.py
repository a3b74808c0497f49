"""The attack settings of the two protocols, and the seed of every attack realisation.

A setting is (label, value, attack name in ``pmwm.attacks.ATTACKS``, parameters). The paper protocol
is the paper's Tables 2-4; the benchmark protocol is Wang, Lavoue, Denis, Baskurt 2010. ``quick``
keeps a few settings of each, for tests and smoke runs.
"""

from __future__ import annotations

import numpy as np

from .published import PAPER_CROP, PAPER_NOISE, PAPER_SMOOTH

Setting = tuple[str, object, str, dict]


def paper_settings(quick: bool) -> dict[str, list[Setting]]:
    """group -> settings of the paper protocol (uniform noise, smoothing lambda 0.03, cropping)."""
    amps = (0.005, 0.01, 0.05) if quick else tuple(PAPER_NOISE)
    its = (5, 20) if quick else tuple(PAPER_SMOOTH)
    crops = (5, 20) if quick else tuple(PAPER_CROP)
    return {
        "noise": [(f"A = {a}", a, "noise_paper", {"amplitude": a}) for a in amps],
        "smoothing": [(f"{k} it.", k, "smooth_laplacian", {"lam": 0.03, "iterations": k}) for k in its],
        "cropping": [(f"{p} %", p, "crop_paper", {"fraction": p / 100}) for p in crops],
    }


def benchmark_settings(quick: bool) -> dict[str, list[Setting]]:
    """group -> settings of the benchmark protocol (Wang et al. 2010)."""
    noise = (0.001, 0.005) if quick else (0.0005, 0.001, 0.003, 0.005)
    its = (10, 50) if quick else (5, 10, 30, 50)
    qbits = (9, 7) if quick else (11, 10, 9, 8, 7)
    crops = (30,) if quick else (10, 30, 50)
    simp = (0.5,) if quick else (0.1, 0.3, 0.5, 0.7, 0.9, 0.95, 0.975)
    subs = ("midpoint",) if quick else ("midpoint", "loop", "sqrt3")
    return {
        "noise": [(f"{100 * a:g} %", a, "noise_benchmark", {"amplitude": a}) for a in noise],
        "smoothing": [(f"{k} it.", k, "smooth_laplacian", {"lam": 0.1, "iterations": k}) for k in its],
        "quantization": [(f"{b} bits", b, "quantize", {"bits": b}) for b in qbits],
        "similarity": [("random", None, "similarity", {})],
        "reordering": [("random", None, "reorder", {})],
        "cropping": [(f"{p} %", p, "crop_plane", {"fraction": p / 100}) for p in crops],
        "simplification": [(f"{100 * r:g} %", r, "simplify", {"ratio": r}) for r in simp],
        "subdivision": [(s, s, "subdivide", {"scheme": s}) for s in subs],
    }


def attack_seed(key_seed: int, group: str, index: int) -> int:
    """The seed of the attack realisation of setting ``index`` of ``group`` for key seed ``key_seed``:
    independent of the method (every method faces the same attacked noise, plane, ...)."""
    tag = sum(ord(ch) * 31**i for i, ch in enumerate(group)) % (2**31)
    return int(np.random.SeedSequence([key_seed, tag, index]).generate_state(1)[0])


__all__ = ["Setting", "attack_seed", "benchmark_settings", "paper_settings"]
