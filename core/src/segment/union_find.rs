//! Disjoint sets over `0..n`, by size, with path halving.

pub(crate) struct UnionFind {
    parent: Vec<u32>,
    size: Vec<u32>,
}

impl UnionFind {
    /// `n` sets of one element each.
    pub(crate) fn new(n: usize) -> Self {
        Self::with_sizes(vec![1; n])
    }

    /// One set per entry, each weighing its entry (e.g. a region's points).
    pub(crate) fn with_sizes(size: Vec<u32>) -> Self {
        Self {
            parent: (0..size.len() as u32).collect(),
            size,
        }
    }

    pub(crate) fn find(&mut self, mut x: usize) -> usize {
        while self.parent[x] as usize != x {
            let grandparent = self.parent[self.parent[x] as usize];
            self.parent[x] = grandparent;
            x = grandparent as usize;
        }
        x
    }

    /// Whether `x` is the root of its set.
    pub(crate) fn is_root(&self, x: usize) -> bool {
        self.parent[x] as usize == x
    }

    /// The weight of the set whose root is `root`.
    pub(crate) fn size(&self, root: usize) -> u32 {
        self.size[root]
    }

    /// Joins the sets of two distinct roots; returns the new root, the
    /// heavier one (`a` on a tie).
    pub(crate) fn union_roots(&mut self, a: usize, b: usize) -> usize {
        let (big, small) = if self.size[a] < self.size[b] {
            (b, a)
        } else {
            (a, b)
        };
        self.parent[small] = big as u32;
        self.size[big] += self.size[small];
        big
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_heavier_set_becomes_the_root_and_sizes_add_up() {
        let mut sets = UnionFind::with_sizes(vec![5, 1, 3]);
        let root = sets.union_roots(1, 2);
        assert_eq!(root, 2);
        assert_eq!(sets.size(2), 4);
        let root = sets.union_roots(0, 2);
        assert_eq!(root, 0, "a tie keeps the first root");
        assert_eq!((sets.find(1), sets.find(2)), (0, 0));
        assert!(sets.is_root(0) && !sets.is_root(2));
        assert_eq!(sets.size(0), 9);
    }
}
