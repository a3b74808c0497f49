"""The robust scheme's keyed site layout: which payload bit each site carries, so that a plane
cutting off half the shape leaves every bit some sites, and the bits' energies are even."""

from __future__ import annotations

import bisect
import itertools
from typing import Optional

import numpy as np

CUT_TESTS = 256  # plane directions the bit assignment is checked against
CUT_KEEP_MIN = 2  # sites a bit should keep under each tested cut
SWAP_ROUNDS = 20  # swap attempts per site in that check


def assign_bits(
    P: np.ndarray, n_bits: int, per_bit: int, seed: int, energy: np.ndarray, unread: Optional[np.ndarray] = None
) -> np.ndarray:
    """Bit index of each site, so that a plane cutting off up to half the sites leaves every bit
    some: pairs of roughly opposite sites (about the centroid) are dealt to bits, richest first in a
    keyed snake order of the bits, then keyed swaps between bits remove the (bit, cut) pairs where a
    bit keeps fewer than ``CUT_KEEP_MIN`` sites, over ``CUT_TESTS`` plane directions cutting 50 % and
    60 % of the sites; then swaps that keep those cuts even out the bits' readable energies
    (``energy`` per site). ``unread`` (sites,) bool: sites known not to read (an earlier marking's);
    a bit left with only such sites then swaps one for a site that reads (``_readable_in_every_bit``)."""
    n = len(P)
    rng = np.random.default_rng(seed)
    u = P - P.mean(axis=0)
    u /= np.maximum(np.linalg.norm(u, axis=1), 1e-300)[:, None]
    free = np.ones(n, bool)
    pairs = []
    for i in rng.permutation(n):  # one iteration per site (hundreds), not per vertex
        if not free[i]:
            continue
        free[i] = False
        cand = np.flatnonzero(free)
        if len(cand) == 0:
            pairs.append([i])
            break
        j = cand[np.argmin(u[cand] @ u[i])]
        free[j] = False
        pairs.append([i, j])
    # dealt richest pair first, in a keyed snake order of the bits (1..n, n..1, ...): even energies
    bit = np.empty(n, np.int64)
    turn = rng.permutation(n_bits)
    rounds = -(-len(pairs) // n_bits)
    snake = np.concatenate([turn if k % 2 == 0 else turn[::-1] for k in range(rounds)])
    pair_energy = np.array([energy[pair].sum() for pair in pairs])
    for k, q in enumerate(np.lexsort((rng.random(len(pairs)), -pair_energy))):
        bit[pairs[q]] = snake[k]
    bit = _spread_over_cuts(P, bit, n_bits, rng, energy)
    return bit if unread is None else _readable_in_every_bit(bit, n_bits, np.asarray(unread, bool), rng)


def _readable_in_every_bit(bit: np.ndarray, n_bits: int, unread: np.ndarray, rng) -> np.ndarray:
    """``bit`` (sites,) int64 with every bit whose sites are all ``unread`` (sites,) bool given a site
    that reads: one of its sites swapped, in a keyed order, for a reading site of a bit that keeps
    another (the cuts may lose a little; a bit that reads nowhere is lost to every copy). One step
    per such bit (a few), not per site."""
    bit = bit.copy()
    reads = np.bincount(bit, weights=~unread, minlength=n_bits)
    for b in rng.permutation(np.flatnonzero(reads == 0)):
        donors = np.flatnonzero(~unread & (reads[bit] >= 2))
        mine = np.flatnonzero(bit == b)
        if len(donors) == 0 or len(mine) == 0:
            break
        i, j = mine[int(rng.integers(len(mine)))], donors[int(rng.integers(len(donors)))]
        reads[bit[j]] -= 1
        reads[b] += 1
        bit[i], bit[j] = bit[j], b
    return bit


def _spread_over_cuts(P: np.ndarray, bit: np.ndarray, n_bits: int, rng, energy: np.ndarray) -> np.ndarray:
    """Keyed local search: swap sites between bits while the number of (bit, cut) pairs with
    fewer than CUT_KEEP_MIN kept sites does not grow (each swap is one site-for-site exchange, so
    every bit keeps its number of sites). Then, under the same rule, swaps between the k-th richest
    and the k-th poorest bit: vertex density varies over a scan, so a site's energy does (ten times
    and more on the dragon), and a bit's error rate is convex in its energy, so at equal total
    energy even bits err least (per-bit variation 0.49 -> 0.41 on a dragon key; the cuts limit it)."""
    d = rng.standard_normal((CUT_TESTS, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    proj = P @ d.T  # (sites, directions)
    # (each direction's quantile along the rows of the transposed copy: the same values, faster)
    proj_t = np.ascontiguousarray(proj.T)
    kept = np.concatenate([proj <= np.quantile(proj_t, q, axis=1) for q in (0.5, 0.4)], axis=1)
    book = _CutBook(kept, bit, n_bits)
    bit = book.bit

    # the draws below read Python structures (one short loop per step, no array scans): the sites of
    # each bit in ascending order, and for each cut its kept sites in ascending order and a flag per site
    members = [sorted(np.flatnonzero(bit == b).tolist()) for b in range(n_bits)]
    kept_t = np.ascontiguousarray(kept.T)  # (cuts, sites)
    kept_sites = [np.flatnonzero(row).tolist() for row in kept_t]
    kept_flag = [row.tolist() for row in kept_t]
    short_cols, try_swap, bisect_right = book.short_cols, book.try_swap, bisect.bisect_right  # (locals)
    for _ in range(SWAP_ROUNDS * len(P)):  # a few thousand cheap steps over sites, not vertices
        # a keyed draw among the short (bit, cut) pairs, in row-major order: the row from the running
        # counts per bit, then the column within that row
        acc = book.short_acc
        total = acc[-1]
        if total == 0:
            break
        k = int(rng.integers(total))
        b = bisect_right(acc, k)
        c = short_cols[b][k - acc[b - 1] if b else k]
        flag, mb = kept_flag[c], members[b]
        mine = [i for i in mb if not flag[i]]  # sites of bit b the cut drops
        n_other = len(kept_sites[c]) - (len(mb) - len(mine))  # sites the cut keeps, of other bits
        if not mine or n_other == 0:
            continue
        i = mine[int(rng.integers(len(mine)))]
        j = _nth_skipping(kept_sites[c], int(rng.integers(n_other)), [m for m in mb if flag[m]])
        if try_swap(i, j):
            a = book.bits[i]  # j's bit, now i's
            mb.remove(i)
            bisect.insort(mb, j)
            members[a].remove(j)
            bisect.insort(members[a], i)

    for _ in range(SWAP_ROUNDS):  # rounds pairing the k-th richest bit with the k-th poorest
        total = np.bincount(bit, weights=energy, minlength=n_bits)
        order = np.argsort(total, kind="stable")
        swapped = False
        for hi, lo in zip(order[::-1][: n_bits // 2], order[: n_bits // 2]):
            gap = total[hi] - total[lo]
            mine, other = np.flatnonzero(bit == hi), np.flatnonzero(bit == lo)
            d = energy[mine][:, None] - energy[other][None, :]
            cost = np.where((d > 0) & (d < gap), np.abs(d - gap / 2), np.inf).ravel()
            n_finite = np.count_nonzero(np.isfinite(cost))
            for k in np.argsort(cost, kind="stable")[:n_finite].tolist():
                if book.try_swap(int(mine[k // len(other)]), int(other[k % len(other)])):
                    swapped = True
                    break
        if not swapped:
            break
    return bit


class _CutBook:
    """The sites each bit keeps under each tested cut, kept up to date through site swaps.

    kept (sites, cuts) bool, bit (sites,) int64 each site's bit (copied: ``self.bit`` is updated by
    the swaps). A bit's row of counts is mirrored in Python integers used as bit sets over the cuts
    (the cuts where it keeps exactly ``need`` sites, and exactly ``need - 1``), so that testing a
    swap is a few AND and popcount operations on 512-bit integers; only an accepted swap (a few
    hundred) touches numpy rows."""

    def __init__(self, kept: np.ndarray, bit: np.ndarray, n_bits: int):
        self.bit = bit.copy()
        self.bits = self.bit.tolist()  # the same, as a Python list (read per step)
        self.kept_n = kept.astype(np.int64)
        self.count = np.zeros((n_bits, kept.shape[1]), np.int64)
        np.add.at(self.count, self.bit, self.kept_n)
        self.need = min(CUT_KEEP_MIN, int(np.bincount(self.bit).min()))
        self.site_cuts = _bit_sets(kept)  # per site: the cuts that keep it
        self.at_need = [0] * n_bits  # per bit: the cuts where it keeps exactly ``need`` sites
        self.one_short = [0] * n_bits  # ... exactly ``need - 1`` (one lost: still short; one gained: not)
        self.short_cols: list[list[int]] = [[] for _ in range(n_bits)]  # the cuts it is short under
        self.shorts = [0] * n_bits
        for b in range(n_bits):
            self._refresh(b)
        self.short_acc = list(itertools.accumulate(self.shorts))  # running (bit, cut) short counts

    def _refresh(self, b: int) -> None:
        row = self.count[b]
        self.at_need[b] = _bit_sets(row == self.need)[0]
        self.one_short[b] = _bit_sets(row == self.need - 1)[0]
        self.short_cols[b] = np.flatnonzero(row < self.need).tolist()
        self.shorts[b] = len(self.short_cols[b])

    def try_swap(self, i: int, j: int) -> bool:
        """Swap sites i and j (of different bits) unless more (bit, cut) pairs would fall short."""
        bits, at_need, one_short = self.bits, self.at_need, self.one_short
        b, a = bits[i], bits[j]
        ki, kj = self.site_cuts[i], self.site_cuts[j]
        lose, gain = ki & ~kj, kj & ~ki  # the cuts where b loses a kept site (a gains one), and gains
        # the change in b's and a's short cuts: must not be positive
        if (
            (lose & at_need[b]).bit_count()
            - (gain & one_short[b]).bit_count()
            + (gain & at_need[a]).bit_count()
            - (lose & one_short[a]).bit_count()
        ) > 0:
            return False
        delta = self.kept_n[j] - self.kept_n[i]
        self.count[b] += delta
        self.count[a] -= delta
        self._refresh(b)
        self._refresh(a)
        self.short_acc = list(itertools.accumulate(self.shorts))
        self.bit[i], self.bit[j] = a, b
        bits[i], bits[j] = a, b
        return True


def _bit_sets(rows: np.ndarray) -> list[int]:
    """Each row of rows (r, c) bool (or one row (c,)) as a Python integer whose bit k is rows[., k]."""
    rows = np.atleast_2d(rows)
    packed = np.packbits(rows, axis=1, bitorder="little")
    return [int.from_bytes(p.tobytes(), "little") for p in packed]


def _nth_skipping(values: list[int], r: int, skip: list[int]) -> int:
    """The r-th (0-based) element of the ascending list ``values`` once the elements ``skip`` (a
    few, all in ``values``, ascending) are left out."""
    if not skip:
        return values[r]
    for p in [bisect.bisect_left(values, x) for x in skip]:  # ascending, as skip
        if p <= r:
            r += 1
        else:
            break
    return values[r]
