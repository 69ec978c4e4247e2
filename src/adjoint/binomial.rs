//! Binomial checkpointing: the order in which a run of n steps is recomputed from a few stored
//! states so that its adjoint meets every step from the last to the first, with the fewest
//! recomputed steps (Griewank & Walther, "Algorithm 799: revolve", ACM TOMS 26(1), 2000,
//! 19–45). Written here: no maintained Rust crate provides the schedule.
//!
//! Level j of a segment is its state after j steps (level 0: its start, always held); step k
//! leads from level k to level k + 1. With s snapshots besides level 0 and a window of w taped
//! steps, a segment of l ≤ w steps is run once and taped whole. A longer one is split at level
//! m: the steps up to m are run and level m stored, the part after m is reversed with s − 1
//! snapshots, m is freed, and the part before m is reversed with s. Counting in blocks of w
//! steps, with β(s, r) = C(s + r, s) and r the least number of repetitions with β(s + 1, r) ≥
//! the segment's blocks (level 0 counts among revolve's snapshots), m is the larger of
//! β(s + 1, r − 2) and the blocks less β(s, r): the least split that leaves both parts at their
//! fewest repetitions, for w = 1 the optimum (checked against every split in a test). Without a snapshot the segment is taped
//! in windows from its end, each recomputed from level 0.

use std::ops::Range;

/// One action of a schedule over the levels of a segment.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Action {
    /// Run from the state held at level `from` to level `to`, storing the levels `store` as
    /// snapshots and taping the steps `tape` (and, when `tape` starts after `from`, the step
    /// before it, whose level the first taped step starts from).
    Run {
        from: usize,
        to: usize,
        store: Vec<usize>,
        tape: Range<usize>,
    },
    /// The adjoint sweeps the taped steps `steps`, the last first; they are dropped after it.
    Reverse(Range<usize>),
    /// Drop the snapshot of level j.
    Free(usize),
}

/// C(s + r, s): the most steps s snapshots reverse with each step run at most r + 1 times.
fn beta(s: usize, r: usize) -> usize {
    let mut b: u128 = 1;
    for i in 1..=s.min(r) as u128 {
        b = b * (s.max(r) as u128 + i) / i;
        if b > usize::MAX as u128 {
            return usize::MAX;
        }
    }
    b as usize
}

/// The schedule reversing `n` steps with `snapshots` stored levels besides level 0 and a window
/// of `window` (≥ 1) taped steps.
pub fn schedule(n: usize, snapshots: usize, window: usize) -> Vec<Action> {
    let mut out = Vec::new();
    reverse(0, n, snapshots, window.max(1), &mut out);
    merge(out)
}

fn reverse(a: usize, b: usize, s: usize, w: usize, out: &mut Vec<Action>) {
    let l = b - a;
    if l == 0 {
        return;
    }
    if l <= w {
        out.push(Action::Run {
            from: a,
            to: b,
            store: Vec::new(),
            tape: a..b,
        });
        out.push(Action::Reverse(a..b));
        return;
    }
    if s == 0 {
        let mut hi = b;
        while hi > a {
            let lo = hi.saturating_sub(w).max(a);
            out.push(Action::Run {
                from: a,
                to: hi,
                store: Vec::new(),
                tape: lo..hi,
            });
            out.push(Action::Reverse(lo..hi));
            hi = lo;
        }
        return;
    }
    let blocks = l.div_ceil(w);
    // level 0 counts among revolve's snapshots: s + 1 of them
    let mut r = 0;
    while beta(s + 1, r) < blocks {
        r += 1;
    }
    let least = if r >= 2 { beta(s + 1, r - 2) } else { 1 };
    let left = least
        .max(blocks.saturating_sub(beta(s, r)))
        .clamp(1, blocks - 1);
    let m = a + left * w;
    out.push(Action::Run {
        from: a,
        to: m,
        store: vec![m],
        tape: m..m,
    });
    reverse(m, b, s - 1, w, out);
    out.push(Action::Free(m));
    reverse(a, m, s, w, out);
}

/// Joins a run that only stores its end with the run that starts there: one run instead of a
/// restart (which refactors the held matrices).
fn merge(actions: Vec<Action>) -> Vec<Action> {
    let mut out: Vec<Action> = Vec::with_capacity(actions.len());
    for a in actions {
        if let (
            Some(Action::Run {
                to,
                store,
                tape: held,
                ..
            }),
            Action::Run {
                from,
                to: end,
                store: more,
                tape,
            },
        ) = (out.last_mut(), &a)
        {
            if held.start == held.end && *from == *to && store.last() == Some(to) {
                *to = *end;
                store.extend(more.iter().copied());
                *held = tape.clone();
                continue;
            }
        }
        out.push(a);
    }
    out
}

/// The steps a schedule runs in all.
pub fn cost(actions: &[Action]) -> usize {
    actions
        .iter()
        .map(|a| match a {
            Action::Run { from, to, .. } => to - from,
            _ => 0,
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    /// Plays a schedule: every step is reversed once, the last first, from a held level or a
    /// taped step before it; at most `s` snapshots and `w` (+1) taped steps are held at once.
    /// Returns the steps run.
    fn play(n: usize, s: usize, w: usize) -> usize {
        let actions = schedule(n, s, w);
        let mut held: BTreeSet<usize> = BTreeSet::from([0]);
        let mut taped: BTreeSet<usize> = BTreeSet::new();
        let mut next = n;
        for a in &actions {
            match a {
                Action::Run {
                    from,
                    to,
                    store,
                    tape,
                } => {
                    assert!(held.contains(from), "{a:?} from a level not held");
                    assert!(to <= &n && from < to);
                    for j in store {
                        assert!(from < j && j <= to);
                        held.insert(*j);
                    }
                    taped.extend(tape.clone());
                    if tape.start > *from {
                        taped.insert(tape.start - 1);
                    }
                    assert!(held.len() <= s + 1, "{} snapshots", held.len() - 1);
                    assert!(taped.len() <= w + 1, "{} taped", taped.len());
                }
                Action::Reverse(steps) => {
                    for k in steps.clone().rev() {
                        assert_eq!(k + 1, next, "step {k} out of order");
                        assert!(taped.contains(&k));
                        assert!(held.contains(&k) || taped.contains(&(k - 1)));
                        next = k;
                    }
                    taped.retain(|&k| k < steps.start);
                }
                Action::Free(j) => {
                    assert!(held.remove(j));
                }
            }
        }
        assert_eq!(next, 0, "every step reversed");
        cost(&actions)
    }

    /// The least number of steps run to reverse l steps with s snapshots, one taped step at a
    /// time, over every split (dynamic programming).
    fn optimum(l: usize, s: usize, memo: &mut Vec<Vec<usize>>) -> usize {
        if memo[l][s] != usize::MAX {
            return memo[l][s];
        }
        let v = if l <= 1 {
            l
        } else if s == 0 {
            l * (l + 1) / 2
        } else {
            (1..l)
                .map(|m| m + optimum(l - m, s - 1, memo) + optimum(m, s, memo))
                .min()
                .unwrap()
        };
        memo[l][s] = v;
        v
    }

    /// With a window of one step the schedule runs as few steps as the best split of every
    /// length up to 60 with up to 5 snapshots.
    #[test]
    fn one_step_windows_are_optimal() {
        let mut memo = vec![vec![usize::MAX; 6]; 61];
        for s in 0..=5 {
            for n in 1..=60 {
                assert_eq!(play(n, s, 1), optimum(n, s, &mut memo), "n = {n}, s = {s}");
            }
        }
        // the optimum in closed form: r·l − β(s + 2, r − 1) + l (revolve's count, the taping
        // runs included), here l = 100, s = 4, r = 4 (β(5, 3) = 56 < 100 ≤ β(5, 4) = 126)
        assert_eq!((beta(5, 3), beta(5, 4)), (56, 126));
        assert_eq!(play(100, 4, 1), 4 * 100 - beta(6, 3) + 100);
    }

    /// Wider windows keep the rules and run fewer steps; a segment that fits is run once.
    #[test]
    fn windows_tape_several_steps() {
        for (n, s, w) in [
            (100, 3, 4),
            (1000, 5, 16),
            (37, 0, 5),
            (64, 2, 64),
            (1, 0, 1),
        ] {
            let c = play(n, s, w);
            assert!(c >= n);
            if w >= n {
                assert_eq!(c, n);
            }
            assert!(c <= play(n, s, 1));
        }
        // 10⁴ steps, 20 snapshots and a window of 50: 200 blocks, r = 2 (β(21, 2) = 253), each
        // step run at most three times
        let c = play(10_000, 20, 50);
        assert!(c <= 3 * 10_000, "{c}");
    }
}
