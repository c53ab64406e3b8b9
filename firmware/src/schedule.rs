//! Key-to-core assignment: [`partition`], exact for two cores (the budget's and the
//! firmware image's), and longest processing time first ([`lpt`]) beyond.
//!
//! Given each key's worst-case cycles per sample (e.g. from [`tactus_isa::wcet::analyse`]) and a
//! number of cores, [`lpt`] sorts the keys by decreasing cost and gives each, in turn, to the
//! core with the smallest total so far. The largest core total (the makespan) is at most
//! 4/3 − 1/(3m) times the optimum for m cores (R. L. Graham, "Bounds on multiprocessing
//! timing anomalies", SIAM J. Appl. Math. 17(2), 1969); the assignment is deterministic
//! (ties: the lower key index first, the lower core index first).

/// One core's share of the keys.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CoreLoad {
    /// Indices into the cost slice given to [`lpt`], in the order they were assigned
    /// (decreasing cost).
    pub keys: Vec<usize>,
    /// Sum of their costs, in core clock cycles.
    pub total: u64,
}

/// Assigns keys with per-key `costs` (core clock cycles) to `cores` cores by longest
/// processing time first; returns one [`CoreLoad`] per core (`cores = 0` is treated as 1).
pub fn lpt(costs: &[u64], cores: usize) -> Vec<CoreLoad> {
    let mut out = vec![CoreLoad::default(); cores.max(1)];
    let mut order: Vec<usize> = (0..costs.len()).collect();
    order.sort_by(|&a, &b| costs[b].cmp(&costs[a]).then(a.cmp(&b)));
    for k in order {
        let core = (0..out.len())
            .min_by_key(|&c| (out[c].total, c))
            .unwrap_or(0);
        out[core].keys.push(k);
        out[core].total += costs[k];
    }
    out
}

/// The largest core total of an assignment (the makespan), in core clock cycles.
pub fn makespan(loads: &[CoreLoad]) -> u64 {
    loads.iter().map(|l| l.total).max().unwrap_or(0)
}

/// An assignment of `costs` to `cores` cores minimising the fullest core's total: exact for
/// two cores (a subset-sum table over the totals, for totals up to 2^22 cycles; beyond
/// that, and for more cores, longest processing time first, which is within 4/3 of the
/// optimum). Returns each key's core.
pub fn partition(costs: &[u64], cores: usize) -> Vec<usize> {
    let total: u64 = costs.iter().sum();
    if cores <= 1 || costs.len() <= 1 {
        return vec![0; costs.len()];
    }
    if cores > 2 || total > 1 << 22 {
        let mut core = vec![0; costs.len()];
        for (c, load) in lpt(costs, cores).iter().enumerate() {
            for &k in &load.keys {
                core[k] = c;
            }
        }
        return core;
    }
    // Core 1's share: some subset of the keys (all of width 0).
    let total = total as usize;
    let reach = SubsetSums::new(costs, &vec![0; costs.len()], 0);
    // The core-1 share closest to half from below (core 0 takes the larger share).
    let best = (0..=total / 2)
        .rev()
        .find(|&s| reach.has(costs.len(), 0, s))
        .unwrap_or(0);
    let mut core = vec![0; costs.len()];
    let mut s = best;
    for i in (0..costs.len()).rev() {
        if !reach.has(i, 0, s) {
            core[i] = 1;
            s -= costs[i] as usize;
        }
    }
    core
}

/// The subset-sum table of [`partition`] and [`partition_capped`]: for keys of `costs`
/// (cycles) and `widths` (converter channels), whether some subset of the first `i` keys
/// has width `w` and cost `s` — per (i, w) a bit set over the costs 0 to their total, each
/// key's row the previous one ORed with itself shifted by the key's cost.
struct SubsetSums {
    /// Widths 0 to `width`, and 64-bit words per row.
    wn: usize,
    words: usize,
    bits: Vec<u64>,
}

impl SubsetSums {
    /// The table for widths up to `width` (the keys' total width) and costs up to their
    /// total; the callers bound its size first.
    fn new(costs: &[u64], widths: &[u32], width: usize) -> SubsetSums {
        let n = costs.len();
        let total: u64 = costs.iter().sum();
        let (wn, words) = (width + 1, (total as usize + 1).div_ceil(64));
        let mut t = SubsetSums {
            wn,
            words,
            bits: vec![0u64; (n + 1) * wn * words],
        };
        t.bits[0] = 1;
        for i in 0..n {
            let (c, k) = (costs[i] as usize, widths[i] as usize);
            let (this, next) = (t.row(i, 0), t.row(i + 1, 0));
            let (before, after) = t.bits.split_at_mut(next);
            let before = &before[this..];
            for w in 0..wn {
                let to = &mut after[w * words..(w + 1) * words];
                to.copy_from_slice(&before[w * words..(w + 1) * words]);
                if w >= k {
                    or_shifted(to, &before[(w - k) * words..(w - k + 1) * words], c);
                }
            }
        }
        t
    }

    fn row(&self, i: usize, w: usize) -> usize {
        (i * self.wn + w) * self.words
    }

    /// Whether some subset of the first `i` keys has width `w` and cost `s`.
    fn has(&self, i: usize, w: usize, s: usize) -> bool {
        self.bits[self.row(i, w) + s / 64] >> (s % 64) & 1 != 0
    }
}

/// [`partition`] with every core holding keys of at most `cap` in all of `widths` (a key's
/// converter channels: a board with converters holds as many keys a core as its parts have
/// channels): the assignment minimising the fullest core's total among those that respect
/// the cap, exact for one or two cores; `None` when none does, or (two cores, a subset-sum
/// table of more than 2^25 entries) beyond what it tabulates. Without a binding cap it is
/// [`partition`].
pub fn partition_capped(
    costs: &[u64],
    widths: &[u32],
    cores: usize,
    cap: u32,
) -> Option<Vec<usize>> {
    let width: u64 = widths.iter().map(|&w| u64::from(w)).sum();
    if width <= u64::from(cap) || costs.len() != widths.len() {
        return (costs.len() == widths.len()).then(|| partition(costs, cores));
    }
    if cores != 2 {
        return None;
    }
    let total: u64 = costs.iter().sum();
    let cap = u64::from(cap);
    let (n, w_all) = (costs.len(), width as usize);
    let cells = (n as u64 + 1) * (width + 1) * (total + 1);
    if cells > 1 << 25 {
        return None;
    }
    let (wn, sn) = (w_all + 1, total as usize + 1);
    let reach = SubsetSums::new(costs, widths, w_all);
    // Core 1's (width, cost) with both cores within the cap, the fullest core least.
    let (w1, s1) = (0..wn)
        .filter(|&w| w as u64 <= cap && width - w as u64 <= cap)
        .flat_map(|w| (0..sn).map(move |s| (w, s)))
        .filter(|&(w, s)| reach.has(n, w, s))
        .min_by_key(|&(_, s)| (s as u64).max(total - s as u64))?;
    let mut core = vec![0; n];
    let (mut w, mut s) = (w1, s1);
    for i in (0..n).rev() {
        if !reach.has(i, w, s) {
            core[i] = 1;
            w -= widths[i] as usize;
            s -= costs[i] as usize;
        }
    }
    Some(core)
}

/// ORs `from` shifted up by `by` bits into `to` (bit sets of the same length, the bits
/// shifted past the end dropped).
fn or_shifted(to: &mut [u64], from: &[u64], by: usize) {
    let (words, bits) = (by / 64, by % 64);
    for j in (words..to.len()).rev() {
        let lo = from[j - words] << bits;
        let carry = match (bits, j.checked_sub(words + 1)) {
            (1.., Some(src)) => from[src] >> (64 - bits),
            _ => 0,
        };
        to[j] |= lo | carry;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The capped partition is optimal among the assignments within the cap: brute force.
    #[test]
    fn the_capped_partition_is_exact_within_its_cap() {
        let mut rng = tactus_runtime::rng::XorShift64::new(0x51ed_27c3);
        for _ in 0..300 {
            let n = 1 + rng.below(10);
            let costs: Vec<u64> = (0..n).map(|_| 1 + rng.below(300) as u64).collect();
            let widths: Vec<u32> = (0..n).map(|_| 1 + rng.below(3) as u32).collect();
            let cap = 2 + rng.below(8) as u32;
            let eval = |core: &[usize]| {
                let (mut t, mut w) = ([0u64; 2], [0u32; 2]);
                for i in 0..n {
                    t[core[i]] += costs[i];
                    w[core[i]] += widths[i];
                }
                (w[0] <= cap && w[1] <= cap).then_some(t[0].max(t[1]))
            };
            let best = (0..1u32 << n)
                .filter_map(|m| {
                    let a: Vec<usize> = (0..n).map(|i| (m >> i & 1) as usize).collect();
                    eval(&a)
                })
                .min();
            let got = partition_capped(&costs, &widths, 2, cap);
            assert_eq!(
                got.as_deref().and_then(eval),
                best,
                "{costs:?} {widths:?} cap {cap}"
            );
        }
        // Nine cheap keys and one dear: the plain partition puts the nine on one core.
        let costs = [900, 100, 100, 100, 100, 100, 100, 100, 100, 100];
        let plain = partition(&costs, 2);
        assert_eq!(plain.iter().filter(|&&c| c == plain[1]).count(), 9);
        let capped = partition_capped(&costs, &[1; 10], 2, 8).unwrap();
        assert!((0..2).all(|c| capped.iter().filter(|&&k| k == c).count() <= 8));
        assert_eq!(partition_capped(&costs, &[1; 10], 2, 4), None);
    }

    #[test]
    fn lpt_balances_and_covers_every_key() {
        let costs = [7, 3, 5, 5, 2, 9, 1];
        let loads = lpt(&costs, 2);
        let mut all: Vec<usize> = loads.iter().flat_map(|l| l.keys.clone()).collect();
        all.sort();
        assert_eq!(all, (0..costs.len()).collect::<Vec<_>>());
        for l in &loads {
            assert_eq!(l.total, l.keys.iter().map(|&k| costs[k]).sum::<u64>());
        }
        // 32 cycles in all: 9+5+2 = 16 and 7+5+3+1 = 16.
        assert_eq!(makespan(&loads), 16);
        assert_eq!(loads[0].keys, vec![5, 3, 4]);
        assert_eq!(loads[1].keys, vec![0, 2, 1, 6]);
    }

    #[test]
    fn lpt_edge_cases() {
        assert_eq!(makespan(&lpt(&[], 2)), 0);
        assert_eq!(lpt(&[4, 4], 0).len(), 1);
        assert_eq!(makespan(&lpt(&[4, 4, 4], 3)), 4);
        // Graham's tight example for m = 2: 3,3,2,2,2 → LPT 7, optimum 6.
        assert_eq!(makespan(&lpt(&[3, 3, 2, 2, 2], 2)), 7);
    }

    /// Graham's bound against the optimum found by brute force on small random instances.
    #[test]
    fn lpt_is_within_four_thirds_of_the_optimum() {
        let mut x = 0x2545_f491_u64;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        for _ in 0..200 {
            let m = 2 + (next() % 2) as usize;
            let n = 1 + (next() % 8) as usize;
            let costs: Vec<u64> = (0..n).map(|_| 1 + next() % 50).collect();
            let lpt_span = makespan(&lpt(&costs, m));
            let mut opt = u64::MAX;
            for code in 0..m.pow(n as u32) {
                let mut totals = vec![0u64; m];
                let mut c = code;
                for &k in &costs {
                    totals[c % m] += k;
                    c /= m;
                }
                opt = opt.min(*totals.iter().max().unwrap());
            }
            // makespan ≤ (4/3 − 1/(3m)) · OPT, in integers.
            assert!(
                3 * m as u64 * lpt_span <= (4 * m as u64 - 1) * opt,
                "{costs:?} on {m}"
            );
            assert!(lpt_span >= opt);
        }
    }

    /// The partition is optimal: brute force over every assignment of small instances.
    #[test]
    fn the_two_core_partition_is_exact() {
        let mut rng = tactus_runtime::rng::XorShift64::new(0x9e37_79b9);
        for _ in 0..300 {
            let n = 1 + rng.below(10);
            let costs: Vec<u64> = (0..n).map(|_| 1 + rng.below(900) as u64).collect();
            let core = partition(&costs, 2);
            let span = |core: &[usize]| {
                let mut t = [0u64; 2];
                for (c, &k) in core.iter().zip(&costs) {
                    t[*c] += k;
                }
                t[0].max(t[1])
            };
            let best = (0..1u32 << n)
                .map(|m| {
                    let a: Vec<usize> = (0..n).map(|i| (m >> i & 1) as usize).collect();
                    span(&a)
                })
                .min()
                .unwrap();
            assert_eq!(span(&core), best, "{costs:?}");
        }
        assert_eq!(partition(&[5, 5], 1), vec![0, 0]);
        assert!(partition(&[], 2).is_empty());
    }
}
