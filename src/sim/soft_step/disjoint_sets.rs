//! Disjoint sets over body indices (union-find): the islands sleeping puts to rest, the joint
//! groups solved as blocks, and the groups whose bounces are settled on one energy.

/// Union by smaller root (each set's root is its smallest index) and path halving. Kept by its
/// owner from step to step where a step should allocate nothing ([`DisjointSets::reset`]).
#[derive(Debug, Clone, Default)]
pub struct DisjointSets {
    parent: Vec<usize>,
}

impl DisjointSets {
    /// `n` sets of one index each.
    pub fn new(n: usize) -> Self {
        let mut sets = Self::default();
        sets.reset(n);
        sets
    }

    /// Back to `n` sets of one index each, keeping the buffer.
    pub fn reset(&mut self, n: usize) {
        self.parent.clear();
        self.parent.extend(0..n);
    }

    /// The root (smallest index) of `x`'s set.
    pub fn root(&mut self, mut x: usize) -> usize {
        let parent = &mut self.parent;
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }

    /// Joins the sets of `a` and `b`.
    pub fn join(&mut self, a: usize, b: usize) {
        let (a, b) = (self.root(a), self.root(b));
        self.parent[a.max(b)] = a.min(b);
    }
}

#[cfg(test)]
mod tests {
    use super::DisjointSets;

    /// Joined through chains in any order, every index finds the smallest of its set.
    #[test]
    fn roots_are_the_smallest_index_of_each_set() {
        let mut sets = DisjointSets::new(8);
        for (a, b) in [(5, 7), (7, 2), (1, 6), (3, 3)] {
            sets.join(a, b);
        }
        let roots: Vec<usize> = (0..8).map(|i| sets.root(i)).collect();
        assert_eq!(roots, [0, 1, 2, 3, 4, 2, 1, 2]);
        sets.reset(3);
        assert_eq!((0..3).map(|i| sets.root(i)).collect::<Vec<_>>(), [0, 1, 2]);
    }
}
