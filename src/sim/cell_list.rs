//! A dense grid of boxes rebuilt every step by counting sort (a cell list, as in molecular
//! dynamics): the soft step's broad phase. Each cell's bodies lie contiguous and in ascending
//! order, so each body finds its partners by a sweep over its few cells, in parallel;
//! no hash lookups and no per-cell allocations. A scene whose boxes would need too many cells
//! (bodies flung far away) is left to the hash grid.

use super::aabb::Aabb;
use super::grid::{Found, merge_found, overlap_test};
use rayon::prelude::*;

/// Bodies spanning more cells than this per axis are tested against every body instead.
const MAX_CELLS_PER_AXIS: f64 = 8.0;

/// Cell coordinates of a box's lowest and highest corners.
type CellRange = ([u32; 3], [u32; 3]);

#[derive(Debug, Clone, Default)]
pub struct CellList {
    inv_cell: f64,
    origin: glam::DVec3,
    dims: [usize; 3],
    /// `entries[starts[c]..starts[c + 1]]`: the bodies in cell `c`, ascending.
    starts: Vec<u32>,
    entries: Vec<u32>,
    /// Each body's cell range; None for oversized bodies and bodies left out.
    ranges: Vec<Option<CellRange>>,
    oversized: Vec<u32>,
    present: Vec<bool>,
}

impl CellList {
    /// Rebuilds over the `boxes` of the bodies marked `present`, with cells of `cell_size`.
    /// Returns false, building nothing, when the boxes would span more than `max_cells` cells.
    pub fn build(
        &mut self,
        boxes: &[Aabb],
        present: &[bool],
        cell_size: f64,
        max_cells: usize,
    ) -> bool {
        self.inv_cell = 1.0 / cell_size;
        let inv = self.inv_cell;
        // NaN spans are not small: such a body is tested against all, and overlaps none.
        let small = |b: &Aabb| ((b.max - b.min) * inv).max_element() < MAX_CELLS_PER_AXIS;
        let bounds = (boxes, present)
            .into_par_iter()
            .with_min_len(1024)
            .filter(|(b, p)| **p && small(b))
            .map(|(b, _)| *b)
            .reduce(|| Aabb::EMPTY, |a, b| a.union(&b));
        let span = ((bounds.max - bounds.min) * inv).floor() + 1.0;
        let empty = bounds == Aabb::EMPTY;
        let fits = span.is_finite() && span.element_product() <= max_cells as f64;
        if !empty && !fits {
            return false;
        }
        self.origin = bounds.min;
        self.dims = if empty {
            [0; 3]
        } else {
            [span.x as usize, span.y as usize, span.z as usize]
        };
        self.present.clear();
        self.present.extend_from_slice(present);
        self.assign_ranges(boxes, small);
        self.sort_into_cells();
        true
    }

    fn assign_ranges(&mut self, boxes: &[Aabb], small: impl Fn(&Aabb) -> bool + Sync) {
        let (origin, inv, dims) = (self.origin, self.inv_cell, self.dims);
        let cell = |v: glam::DVec3| {
            let c = ((v - origin) * inv).floor();
            [0, 1, 2].map(|k| (c[k].max(0.0) as usize).min(dims[k] - 1) as u32)
        };
        self.ranges.clear();
        self.ranges.par_extend(
            (boxes, &self.present)
                .into_par_iter()
                .with_min_len(1024)
                .map(|(b, &p)| (p && small(b)).then(|| (cell(b.min), cell(b.max)))),
        );
        self.oversized.clear();
        self.oversized.extend(
            (0..boxes.len() as u32)
                .filter(|&i| self.present[i as usize] && self.ranges[i as usize].is_none()),
        );
    }

    fn index(&self, c: [u32; 3]) -> usize {
        (c[0] as usize * self.dims[1] + c[1] as usize) * self.dims[2] + c[2] as usize
    }

    fn for_cells(&self, (lo, hi): CellRange, mut f: impl FnMut(usize)) {
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    f(self.index([x, y, z]));
                }
            }
        }
    }

    /// Counting sort of the bodies into their cells (ascending within each cell).
    fn sort_into_cells(&mut self) {
        let cells = self.dims.iter().product::<usize>();
        let mut starts = std::mem::take(&mut self.starts);
        starts.clear();
        starts.resize(cells + 1, 0);
        for range in self.ranges.iter().flatten() {
            self.for_cells(*range, |c| starts[c + 1] += 1);
        }
        for c in 0..cells {
            starts[c + 1] += starts[c];
        }
        let mut next = starts.clone();
        let mut entries = std::mem::take(&mut self.entries);
        entries.clear();
        entries.resize(starts[cells] as usize, 0);
        for (i, range) in self.ranges.iter().enumerate() {
            if let Some(range) = range {
                self.for_cells(*range, |c| {
                    entries[next[c] as usize] = i as u32;
                    next[c] += 1;
                });
            }
        }
        self.entries = entries;
        self.starts = starts;
    }

    /// Every pair (i < j, sorted, each once) of bodies whose boxes overlap, at least one of them
    /// `awake`, for which `keep(i, j)`: two bodies in cells are reported in the first cell they
    /// share. Returns the pairs and the number of box tests.
    ///
    /// Each body finds its partners of higher index, so the bodies' finds, in body order, are
    /// already sorted, and the work splits evenly over the bodies (a pile's dense cells made a
    /// split over cells run on one core).
    pub fn pairs_with_awake(
        &self,
        awake: &[bool],
        boxes: &[Aabb],
        keep: impl Fn(usize, usize) -> bool + Sync,
    ) -> (Vec<(u32, u32)>, usize) {
        let consider = overlap_test(awake, boxes, keep);
        let n = self.present.len();
        let found = (0..n).into_par_iter().with_min_len(512).fold(
            || (Vec::new(), 0),
            |mut found: Found, a| {
                let from = found.0.len();
                match self.ranges[a] {
                    Some(range) => self.partners_in_cells(a, range, &consider, &mut found),
                    None if self.present[a] => {
                        // An oversized body is tested against every body of higher index.
                        for b in (a + 1..n).filter(|&b| self.present[b]) {
                            consider(a, b, &mut found);
                        }
                    }
                    None => {}
                }
                found.0[from..].sort_unstable();
                found
            },
        );
        merge_found(found.collect())
    }

    /// Body `a`'s partners of higher index: those sharing a cell with it (each in the first
    /// cell they share) and the oversized ones.
    fn partners_in_cells(
        &self,
        a: usize,
        range: CellRange,
        consider: &impl Fn(usize, usize, &mut Found),
        found: &mut Found,
    ) {
        self.for_cells(range, |c| {
            let list = &self.entries[self.starts[c] as usize..self.starts[c + 1] as usize];
            let above = list.partition_point(|&b| b as usize <= a);
            for &b in &list[above..] {
                if self.first_shared_cell(a, b as usize) == c {
                    consider(a, b as usize, found);
                }
            }
        });
        for &o in self.oversized.iter().filter(|&&o| o as usize > a) {
            consider(a, o as usize, found);
        }
    }

    /// The cell index of the lowest cell two bodies' ranges share (both in cells).
    fn first_shared_cell(&self, a: usize, b: usize) -> usize {
        let ((lo_a, _), (lo_b, _)) = (
            self.ranges[a].expect("bodies in cells have ranges"),
            self.ranges[b].expect("bodies in cells have ranges"),
        );
        self.index([0, 1, 2].map(|k| lo_a[k].max(lo_b[k])))
    }

    pub fn heap_bytes(&self) -> usize {
        self.starts.capacity() * 4
            + self.entries.capacity() * 4
            + self.ranges.capacity() * std::mem::size_of::<Option<CellRange>>()
            + self.oversized.capacity() * 4
            + self.present.capacity()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// Boxes of many sizes (a few spanning more than eight cells), some bodies left out and
    /// some asleep, against the test of every pair.
    #[test]
    fn pairs_match_every_pair_tested() {
        let mut rng = crate::sim::rng::Rng::new(12345);
        let mut next = move || rng.unit();
        let n = 1500;
        let boxes: Vec<Aabb> = (0..n)
            .map(|k: usize| {
                let centre = DVec3::new(next(), next(), next()) * 60.0;
                let half = if k.is_multiple_of(97) {
                    20.0
                } else {
                    0.3 + 1.5 * next()
                };
                Aabb {
                    min: centre - DVec3::splat(half),
                    max: centre + DVec3::splat(half),
                }
            })
            .collect();
        let present: Vec<bool> = (0..n).map(|k| k % 13 != 5).collect();
        let awake: Vec<bool> = (0..n).map(|k| k % 3 != 0).collect();
        let keep = |i: usize, j: usize| !(i + j).is_multiple_of(11);
        let mut cells = CellList::default();
        assert!(cells.build(&boxes, &present, 4.0, 1 << 20));
        assert!(!cells.oversized.is_empty());
        let (pairs, _) = cells.pairs_with_awake(&awake, &boxes, keep);
        let mut expected = Vec::new();
        for i in 0..n {
            for j in i + 1..n {
                if present[i]
                    && present[j]
                    && (awake[i] || awake[j])
                    && boxes[i].overlaps(&boxes[j])
                    && keep(i, j)
                {
                    expected.push((i as u32, j as u32));
                }
            }
        }
        assert!(expected.len() > 1000, "{}", expected.len());
        assert_eq!(pairs, expected);
    }
}
