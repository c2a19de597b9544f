//! A grid of boxes rebuilt every step by counting sort (a cell list, as in molecular dynamics):
//! the soft step's broad phase. Each cell's bodies lie contiguous and in ascending order, so
//! each body finds its partners by a sweep over its few cells, in parallel; no per-cell
//! allocations. Cells are dense over the boxes' bounds while those fit a budget; a scene spread
//! wider (layers far apart, bodies flung away) hashes its cells into a table of about two
//! slots per entry instead (Teschner et al. 2003, "Optimized spatial hashing for collision
//! detection of deformable objects"), where unrelated cells sharing a slot only cost box tests.

use super::aabb::Aabb;
use super::grid::{Found, merge_found, overlap_test};
use glam::DVec3;
use rayon::prelude::*;

/// Bodies spanning more cells than this per axis are tested against every body instead.
const MAX_CELLS_PER_AXIS: f64 = 8.0;

/// Cell coordinates of a box's lowest and highest corners.
type CellRange = ([u32; 3], [u32; 3]);

/// How cell coordinates map to the cells' slots.
#[derive(Debug, Clone, Copy, Default)]
enum Layout {
    /// One slot per cell of a dense `dims` block.
    Dense([usize; 3]),
    /// Cells hashed into `mask + 1` slots (a power of two).
    Hashed { mask: usize },
    #[default]
    Empty,
}

/// Where the cells lie and how they map to slots.
#[derive(Debug, Clone, Copy, Default)]
struct Frame {
    origin: DVec3,
    inv_cell: f64,
    layout: Layout,
}

#[derive(Debug, Clone, Default)]
pub struct CellList {
    frame: Frame,
    /// `entries[starts[s]..starts[s + 1]]`: the bodies in slot `s`, ascending.
    starts: Vec<u32>,
    entries: Vec<u32>,
    /// Each body's cell range; None for oversized bodies and bodies left out.
    ranges: Vec<Option<CellRange>>,
    oversized: Vec<u32>,
    present: Vec<bool>,
}

impl Frame {
    /// The cells a box spans, its corners clamped into the grid (a box outside it still meets
    /// every body it may overlap: the clamp keeps the coordinates' order).
    fn range(&self, b: &Aabb) -> CellRange {
        let top = match self.layout {
            Layout::Dense(dims) => dims.map(|d| (d - 1) as f64),
            _ => [u32::MAX as f64; 3],
        };
        // Clamped first, the cast's truncation is the floor (f64::floor is a libm call on
        // baseline x86-64); a NaN coordinate goes to 0.
        let cell = |v: DVec3| {
            let c = (v - self.origin) * self.inv_cell;
            [0, 1, 2].map(|k| c[k].max(0.0).min(top[k]) as u32)
        };
        (cell(b.min), cell(b.max))
    }

    fn slot_count(&self) -> usize {
        match self.layout {
            Layout::Dense(dims) => dims.iter().product(),
            Layout::Hashed { mask } => mask + 1,
            Layout::Empty => 0,
        }
    }

    fn slot(&self, c: [u32; 3]) -> usize {
        match self.layout {
            Layout::Dense(dims) => {
                (c[0] as usize * dims[1] + c[1] as usize) * dims[2] + c[2] as usize
            }
            Layout::Hashed { mask } => {
                // Teschner's primes mixed by MurmurHash3's finaliser, whose low bits depend on
                // every coordinate (the table is indexed by the low bits).
                let mut h = (c[0] as u64).wrapping_mul(73_856_093)
                    ^ (c[1] as u64).wrapping_mul(19_349_663)
                    ^ (c[2] as u64).wrapping_mul(83_492_791);
                h ^= h >> 33;
                h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
                (h ^ (h >> 33)) as usize & mask
            }
            Layout::Empty => 0,
        }
    }
}

impl CellList {
    /// Rebuilds over the `boxes` of the bodies marked `present`, with cells of `cell_size`: dense
    /// while the boxes' bounds span at most `max_cells` cells, hashed beyond.
    pub fn build(&mut self, boxes: &[Aabb], present: &[bool], cell_size: f64, max_cells: usize) {
        let inv = 1.0 / cell_size;
        let small = |b: &Aabb| is_small(b, inv);
        let bounds = (boxes, present)
            .into_par_iter()
            .with_min_len(1024)
            .filter(|(b, p)| **p && small(b))
            .map(|(b, _)| *b)
            .reduce(|| Aabb::EMPTY, |a, b| a.union(&b));
        let span = ((bounds.max - bounds.min) * inv).floor() + 1.0;
        let layout = if bounds == Aabb::EMPTY {
            Layout::Empty
        } else if span.is_finite() && span.element_product() <= max_cells as f64 {
            Layout::Dense([span.x as usize, span.y as usize, span.z as usize])
        } else {
            Layout::Hashed { mask: 0 }
        };
        self.frame = Frame {
            origin: if bounds == Aabb::EMPTY {
                DVec3::ZERO
            } else {
                bounds.min
            },
            inv_cell: inv,
            layout,
        };
        self.present.clear();
        self.present.extend_from_slice(present);
        self.assign_ranges(boxes);
        if let Layout::Hashed { mask } = &mut self.frame.layout {
            let entries: usize = self.ranges.iter().flatten().map(cell_count).sum();
            *mask = (2 * entries).next_power_of_two().max(64) - 1;
        }
        self.sort_into_cells();
    }

    fn assign_ranges(&mut self, boxes: &[Aabb]) {
        let frame = self.frame;
        self.ranges.clear();
        self.ranges.par_extend(
            (boxes, &self.present)
                .into_par_iter()
                .with_min_len(1024)
                .map(|(b, &p)| (p && is_small(b, frame.inv_cell)).then(|| frame.range(b))),
        );
        self.oversized.clear();
        self.oversized.extend(
            (0..boxes.len() as u32)
                .filter(|&i| self.present[i as usize] && self.ranges[i as usize].is_none()),
        );
    }

    /// Calls `f` with each cell of `range` and its slot.
    fn for_cells(&self, (lo, hi): CellRange, mut f: impl FnMut([u32; 3], usize)) {
        // In u64: hashed cells far out reach u32::MAX, where `hi + 1` would overflow.
        let axis = |k: usize| lo[k] as u64..hi[k] as u64 + 1;
        for x in axis(0) {
            for y in axis(1) {
                for z in axis(2) {
                    let cell = [x as u32, y as u32, z as u32];
                    f(cell, self.frame.slot(cell));
                }
            }
        }
    }

    fn slot_bodies(&self, slot: usize) -> &[u32] {
        &self.entries[self.starts[slot] as usize..self.starts[slot + 1] as usize]
    }

    /// Counting sort of the bodies into their slots (ascending within each slot).
    fn sort_into_cells(&mut self) {
        let slots = self.frame.slot_count();
        let mut starts = std::mem::take(&mut self.starts);
        starts.clear();
        starts.resize(slots + 1, 0);
        for range in self.ranges.iter().flatten() {
            self.for_cells(*range, |_, s| starts[s + 1] += 1);
        }
        for s in 0..slots {
            starts[s + 1] += starts[s];
        }
        let mut next = starts.clone();
        let mut entries = std::mem::take(&mut self.entries);
        entries.clear();
        entries.resize(starts[slots] as usize, 0);
        for (i, range) in self.ranges.iter().enumerate() {
            if let Some(range) = range {
                self.for_cells(*range, |_, s| {
                    entries[next[s] as usize] = i as u32;
                    next[s] += 1;
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
        self.for_cells(range, |cell, slot| {
            let list = self.slot_bodies(slot);
            if list.len() < 2 {
                return;
            }
            let above = list.partition_point(|&b| b as usize <= a);
            for &b in &list[above..] {
                // A hashed slot also holds other cells' bodies: only this cell's first meeting
                // counts (a body twice in one slot is reported twice, and merged).
                if self.first_shared_cell(a, b as usize) == Some(cell) {
                    consider(a, b as usize, found);
                }
            }
        });
        for &o in self.oversized.iter().filter(|&&o| o as usize > a) {
            consider(a, o as usize, found);
        }
    }

    /// The lowest cell two bodies' ranges share, if both are in cells.
    fn first_shared_cell(&self, a: usize, b: usize) -> Option<[u32; 3]> {
        let ((lo_a, _), (lo_b, _)) = (self.ranges[a]?, self.ranges[b]?);
        Some([
            lo_a[0].max(lo_b[0]),
            lo_a[1].max(lo_b[1]),
            lo_a[2].max(lo_b[2]),
        ])
    }

    pub fn heap_bytes(&self) -> usize {
        self.starts.capacity() * 4
            + self.entries.capacity() * 4
            + self.ranges.capacity() * std::mem::size_of::<Option<CellRange>>()
            + self.oversized.capacity() * 4
            + self.present.capacity()
    }
}

/// Whether a box spans few enough cells to go into them (a NaN span is not small: such a body
/// is tested against all, and overlaps none).
fn is_small(b: &Aabb, inv_cell: f64) -> bool {
    ((b.max - b.min) * inv_cell).max_element() < MAX_CELLS_PER_AXIS
}

fn cell_count((lo, hi): &CellRange) -> usize {
    (0..3).map(|k| (hi[k] - lo[k]) as usize + 1).product()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// Boxes of many sizes (a few spanning more than eight cells), some far away and some NaN,
    /// some bodies left out and some asleep, against the test of every pair: in dense cells,
    /// in hashed cells (a budget of 64), and with the far bodies forcing the hash.
    #[test]
    fn pairs_match_every_pair_tested() {
        let mut rng = crate::sim::rng::Rng::new(12345);
        let mut next = move || rng.unit();
        let n = 1500;
        let mut boxes: Vec<Aabb> = (0..n)
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
        let check = |boxes: &[Aabb], max_cells: usize, hashed: bool| {
            let mut cells = CellList::default();
            cells.build(boxes, &present, 4.0, max_cells);
            assert!(!cells.oversized.is_empty());
            assert_eq!(matches!(cells.frame.layout, Layout::Hashed { .. }), hashed);
            let (pairs, _) = cells.pairs_with_awake(&awake, boxes, keep);
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
        };
        check(&boxes, 1 << 20, false);
        check(&boxes, 64, true);
        // Two overlapping pairs at 1e15 and 1e300, one box reaching past the others, a NaN box.
        let at = |c: DVec3, h: f64| Aabb {
            min: c - DVec3::splat(h),
            max: c + DVec3::splat(h),
        };
        boxes[1] = at(DVec3::splat(1e15), 1.0);
        boxes[2] = at(DVec3::splat(1e15 + 0.5), 1.0);
        boxes[3] = at(DVec3::new(-1e300, 1e300, 0.0), 1.0);
        boxes[4] = at(DVec3::new(-1e300, 1e300, 0.0), 2.0);
        boxes[6] = at(DVec3::ZERO, f64::NAN);
        check(&boxes, 1 << 20, true);
    }
}
