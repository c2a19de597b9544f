//! The order in which the coursework's contact loop meets body pairs: the broad phase's sorted
//! candidates merged with pairs found later (a body moved out of its proxy box mid-loop), each
//! pair once, in (i, j) order, exactly as the all-pairs loop would meet them.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// Where a pair handed out by [`PairQueue::pop`] came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PairSource {
    /// Index into the candidate list the queue was built from.
    Candidate(usize),
    /// Pushed with [`PairQueue::push_later`].
    Requeried,
}

#[derive(Debug, Default)]
pub struct PairQueue {
    candidates: Vec<(u32, u32)>,
    next_candidate: usize,
    later: BinaryHeap<Reverse<(u32, u32)>>,
    last: Option<(u32, u32)>,
}

fn ordered(a: usize, b: usize) -> (u32, u32) {
    if a < b {
        (a as u32, b as u32)
    } else {
        (b as u32, a as u32)
    }
}

impl PairQueue {
    /// A queue over `candidates`, which must be sorted and free of duplicates.
    pub fn new(candidates: Vec<(u32, u32)>) -> Self {
        Self {
            candidates,
            ..Self::default()
        }
    }

    pub fn candidates(&self) -> &[(u32, u32)] {
        &self.candidates
    }

    /// Adds the pair {a, b} if the loop has not passed it yet.
    pub fn push_later(&mut self, a: usize, b: usize) {
        let pair = ordered(a, b);
        if self.last.is_none_or(|last| pair > last) {
            self.later.push(Reverse(pair));
        }
    }

    /// The candidate `ahead` places after the next one from the list, if any: a later pair of
    /// the loop (pairs pushed later may come between), whose data may be asked for early.
    pub fn candidate_ahead(&self, ahead: usize) -> Option<(usize, usize)> {
        let (i, j) = *self.candidates.get(self.next_candidate + ahead)?;
        Some((i as usize, j as usize))
    }

    /// The next pair (i < j) in order, each pair once.
    pub fn pop(&mut self) -> Option<((usize, usize), PairSource)> {
        loop {
            let from_list = self.candidates.get(self.next_candidate).copied();
            let from_heap = self.later.peek().map(|r| r.0);
            let (pair, source) = match (from_list, from_heap) {
                (None, None) => return None,
                (Some(a), Some(b)) if b < a => {
                    self.later.pop();
                    (b, PairSource::Requeried)
                }
                (Some(a), _) => {
                    self.next_candidate += 1;
                    (a, PairSource::Candidate(self.next_candidate - 1))
                }
                (None, Some(b)) => {
                    self.later.pop();
                    (b, PairSource::Requeried)
                }
            };
            if self.last == Some(pair) {
                continue;
            }
            self.last = Some(pair);
            return Some(((pair.0 as usize, pair.1 as usize), source));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merges_in_order_without_duplicates() {
        let mut q = PairQueue::new(vec![(0, 1), (0, 3), (2, 3)]);
        assert_eq!(q.pop(), Some(((0, 1), PairSource::Candidate(0))));
        q.push_later(2, 1); // (1, 2): after (0, 1)
        q.push_later(0, 1); // already passed: dropped
        q.push_later(3, 0); // a candidate too: handed out once
        assert_eq!(q.pop(), Some(((0, 3), PairSource::Candidate(1))));
        assert_eq!(q.pop(), Some(((1, 2), PairSource::Requeried)));
        assert_eq!(q.pop(), Some(((2, 3), PairSource::Candidate(2))));
        assert_eq!(q.pop(), None);
    }
}
