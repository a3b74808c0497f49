"""On meshes too small for 4 sites per coded bit: the payload's codeword on 2 sites per coded bit against the
payload alone (pmwm's choice there), on 6 corpus shapes x 7 attacks. A measurement for
docs/decisions/110-payload-code.md, not part of pmwm.

Run: python benchmarks/code_small_meshes.py coded2    (and: ... uncoded)
"""

import sys

import numpy as np

import pmwm
from pmwm import attacks
from pmwm.schemes.robust import key_data, embed as robust_embed
from pmwm_bench.corpus import generate

mode = sys.argv[1]
res_ok = {}
for fam, seed in [("cad2", 13), ("cad4", 16), ("ellipsoid", 4), ("cad4", 7), ("cad2", 21), ("ellipsoid", 22)]:
    V, F = generate(fam, seed)
    try:
        A = robust_embed(
            V,
            F,
            pmwm.EmbedOptions(payload="OWNR", seed=seed, progressive=False),
            sites_per_bit=3 if mode == "coded2" else 6,
        )
    except pmwm.PayloadError as e:
        print(fam, seed, "refused", e)
        continue
    code = key_data(A.key).code
    rng = np.random.default_rng(seed)
    cases = {
        "simp30": lambda: attacks.simplify(*attacks.similarity(A.vertices, F, seed=1), 0.3),
        "simp50m": lambda: attacks.simplify(*attacks.similarity(A.vertices * [-1, 1, 1], F[:, ::-1], seed=2), 0.5),
        "smooth": lambda: attacks.smooth_laplacian(A.vertices, F, 0.4, 4),
        "noise": lambda: attacks.noise_benchmark(A.vertices, F, 0.0015, seed=3),
        "over25": lambda: (
            pmwm.embed(
                A.vertices, F, pmwm.EmbedOptions(payload="THIEF", seed=seed + 7, strength=5.0, progressive=False)
            ).vertices,
            F,
        ),
        "over35": lambda: (
            pmwm.embed(
                A.vertices, F, pmwm.EmbedOptions(payload="THIEF", seed=seed + 8, strength=7.0, progressive=False)
            ).vertices,
            F,
        ),
        "quant8chain": lambda: attacks.quantize(*attacks.simplify(*attacks.similarity(A.vertices, F, seed=4), 0.3), 8),
    }
    for name, f in cases.items():
        try:
            W, G = f()
        except pmwm.PayloadError:
            continue
        v = pmwm.verify(W, G, A.key)
        ok = v.payload == "OWNR"
        res_ok.setdefault(name, []).append(ok)
        print(
            mode,
            fam,
            seed,
            len(V),
            code is not None,
            len(A.carriers),
            name,
            v.marked,
            ok,
            v.bit_errors,
            f"{v.p_value:.1g}",
            flush=True,
        )
print(
    mode,
    {k: f"{sum(v)}/{len(v)}" for k, v in res_ok.items()},
    "total",
    sum(sum(v) for v in res_ok.values()),
    "/",
    sum(len(v) for v in res_ok.values()),
)
