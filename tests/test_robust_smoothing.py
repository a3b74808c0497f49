"""The robust scheme under Laplacian smoothing: a copy smoothed by five uniform steps (lambda 0.5) keeps
the marked vertex order and is read by index; the payload must be confirmed, not only the mark found."""

from __future__ import annotations

import pytest
from pmwm_bench import corpus

import pmwm
from pmwm import attacks
from pmwm.schemes.robust import embed as robust_embed, verify as robust_verify


@pytest.mark.parametrize("family, seed", [("cad4", 1), pytest.param("thin", 3, marks=pytest.mark.slow)])
def test_five_uniform_laplacian_steps_keep_the_payload(family, seed):
    """Small generated parts (a 4-fold flange, thin rods and a fin: a few thousand vertices, so the payload
    goes without the BCH code and one wrong bit leaves it unconfirmed), marked, then smoothed five times
    with uniform weights and lambda 0.5: the verdict is marked and shows the payload."""
    V, F = corpus.generate(family, seed)
    res = robust_embed(V, F, pmwm.EmbedOptions(payload="ACME 2026", seed=seed, progressive=False))
    X, G = attacks.smooth_laplacian(res.vertices, res.faces, lam=0.5, iterations=5)
    v = robust_verify(X, G, res.key)
    assert v.marked and v.payload_confirmed and v.payload == "ACME 2026", (v.p_value, v.detail)
