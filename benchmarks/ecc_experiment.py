"""Would an error-correcting code help the robust scheme? A measurement, not part of pmwm.

The 64-bit payload either as is (6 sites per bit, the default: 384 sites) or encoded with the K = 7
(133, 171) rate-1/2 convolutional code plus a zero tail (140 coded bits, 2 sites each: 280 sites), at
equal embedding energy (the coded strength scaled until the vertex RMSE matches), decoded by soft Viterbi on the robust
reader's per-bit scores (inverse-variance weighted sums: log-likelihood ratios up to a factor).
Erasures (score 0) count as errors in both columns (pmwm.verify would flip a keyed coin for them).

Run: PMWM_TEST_DATA=../shared/data python benchmarks/ecc_experiment.py dragon 3
(a catalogue name of pmwm_bench.models, a file name in the data folder, or a path).
"""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import load  # noqa: E402

import pmwm  # noqa: E402
from pmwm import attacks, metrics  # noqa: E402
from pmwm.schemes.robust import embed as robust_embed  # noqa: E402  (takes sites_per_bit)
from pmwm.schemes.robust import read_scores  # noqa: E402

G = (0o133, 0o171)
K = 7
NS = 1 << (K - 1)


def parity(x):
    return bin(x).count("1") & 1


# state = last K-1 input bits; output for (state, bit)
OUT = np.zeros((NS, 2, 2), np.int8)
NXT = np.zeros((NS, 2), np.int64)
for s in range(NS):
    for b in range(2):
        reg = (b << (K - 1)) | s
        OUT[s, b] = [parity(reg & g) for g in G]
        NXT[s, b] = reg >> 1
# the two (state, bit) pairs, as 2 * state + bit, that lead to each state (ties: lowest first)
PRED = np.stack([np.flatnonzero(NXT.ravel() == s) for s in range(NS)])


def encode(bits):
    s = 0
    out = []
    for b in list(bits) + [0] * (K - 1):
        out += list(OUT[s, b])
        s = NXT[s, b]
    return np.array(out, np.uint8)


def viterbi(llr, n):  # llr > 0 means coded bit 1
    T = len(llr) // 2
    metric = np.full(NS, -np.inf)
    metric[0] = 0
    back = np.zeros((T, NS), np.int64)
    bitb = np.zeros((T, NS), np.int8)
    sgn = 2.0 * OUT - 1.0  # (NS, 2, 2)
    for t in range(T):
        llr_t = llr[2 * t : 2 * t + 2]
        cand = (metric[:, None] + (sgn * llr_t).sum(axis=2)).ravel()  # (NS * 2,), index 2 s + b
        pick = PRED[np.arange(NS), np.argmax(cand[PRED], axis=1)]  # best of each state's 2 predecessors
        metric = cand[pick]
        back[t] = pick // 2
        bitb[t] = pick % 2
    s = 0
    out = []
    for t in range(T - 1, -1, -1):
        out.append(bitb[t, s])
        s = back[t, s]
    return np.array(out[::-1][:n], np.uint8)


assert (viterbi(2.0 * encode([1, 0, 1, 1, 0]) - 1, 5) == [1, 0, 1, 1, 0]).all()
name = sys.argv[1]
keys = int(sys.argv[2])
V, F = load(name)
att = {
    "noise 0.01": lambda M: attacks.noise_paper(M, F, 0.01, seed=1),
    "noise 0.03": lambda M: attacks.noise_paper(M, F, 0.03, seed=1),
    "noise 0.05": lambda M: attacks.noise_paper(M, F, 0.05, seed=1),
    "smooth 30": lambda M: attacks.smooth_laplacian(M, F, 0.1, 30),
    "smooth 50": lambda M: attacks.smooth_laplacian(M, F, 0.1, 50),
    "quant 7": lambda M: attacks.quantize(M, F, 7),
    "crop 50": lambda M: attacks.crop_plane(M, F, 0.5, seed=3),
    "simp 90": lambda M: attacks.simplify(M, F, 0.9),
    "simp 95": lambda M: attacks.simplify(M, F, 0.95),
}
res = {}
for k in range(keys):
    info = np.random.default_rng(50 + k).integers(0, 2, 64).astype(np.uint8)
    coded = encode(info)
    r_u = robust_embed(V, F, pmwm.EmbedOptions(bits="".join(map(str, info)), seed=k))
    strength = 2.0 * np.sqrt(384 / 280)
    for _ in range(2):  # the bump radius depends on the site spacing: match the vertex RMSE itself
        r_c = robust_embed(
            V, F, pmwm.EmbedOptions(bits="".join(map(str, coded)), seed=k, strength=strength), sites_per_bit=2
        )
        strength *= r_u.rmse / r_c.rmse
    if k == 0:
        for lab, r in (("uncoded", r_u), ("coded", r_c)):
            print(
                name,
                lab,
                "sites",
                len(r.carriers),
                "rmse %.4f" % (100 * r.rmse / metrics.bbox_diagonal(V)),
                "mrms %.4f" % metrics.surface_distance(V, F, r.vertices, F, 20000, seed=0)[0],
                flush=True,
            )
    for a, fn in att.items():
        for lab, r in (("uncoded", r_u), ("coded", r_c)):
            X, FF = fn(r.vertices)[:2]
            sc, _, _ = read_scores(X, FF, r.key)
            scr = r.key.stream("scramble", r.key.n_bits)
            llr = np.where(scr == 1, -sc, sc)  # undo the keyed XOR: bit 1 <-> positive score on unscrambled
            if lab == "uncoded":
                got = (llr > 0).astype(np.uint8)
            else:
                got = viterbi(llr, 64)
            e = int((got != info).sum())
            res.setdefault((a, lab), []).append(e)
for a in att:
    u, c = res[(a, "uncoded")], res[(a, "coded")]
    print(
        f"{name} {a:11s} uncoded errors {u} BER {np.mean(u) / 64:.3f} exact {sum(x == 0 for x in u)}/{keys} | "
        f"coded errors {c} BER {np.mean(c) / 64:.3f} exact {sum(x == 0 for x in c)}/{keys}",
        flush=True,
    )
