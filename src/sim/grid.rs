//! A uniform hash grid of boxes: which bodies' boxes may overlap, found cell by cell, and kept up
//! to date one body at a time while contacts are being resolved.

use super::aabb::Aabb;
use super::buffer;
use super::cell_table::CellTable;
use super::parallel;
use glam::DVec3;
use rayon::prelude::*;

/// One body in one cell. Two bodies sharing a cell meet there first when, along each axis, the
/// cell is the lowest of one of their ranges (the first shared cell is the maximum of the two
/// lowest corners): the walk decides that from the two entries alone, without looking up
/// either body's range (at scatter-100000 those lookups were 41 % of the walk's samples, a sixth
/// of the step). Body indices take 29 bits: half a billion bodies, far beyond what fits in
/// memory at 300 bytes each.
#[derive(Clone, Copy)]
struct CellEntry(u32);

impl CellEntry {
    const FLAGS: u32 = 29;

    fn new(body: usize, lowest: [bool; 3]) -> Self {
        debug_assert!(body < 1 << Self::FLAGS);
        let flags = lowest[0] as u32 | (lowest[1] as u32) << 1 | (lowest[2] as u32) << 2;
        Self(body as u32 | flags << Self::FLAGS)
    }

    fn body(self) -> u32 {
        self.0 & ((1 << Self::FLAGS) - 1)
    }

    /// Whether this cell is the first the two entries' bodies share.
    fn first_meeting(self, other: CellEntry) -> bool {
        (self.0 | other.0) >> Self::FLAGS == 0b111
    }
}

/// Cells spanned by a box more than this many per axis make a body "oversized": it is tested
/// against every other body instead of filling thousands of cells (floors, walls).
const MAX_CELLS_PER_AXIS: i64 = 8;

/// A cell's coordinates along the three axes.
type Cell = [i32; 3];

/// The cell holding coordinate `v` (in cells): its floor, clamped to +-2^30 first so it fits
/// an i32 (a body at 1e300 lands in the last cell, with every other body that far out). By
/// hand: `f64::floor` is a libm call on baseline x86-64, and this runs for every body that
/// moves. Half the size of i64 corners: `ranges` was 5.6 MB at 100,000 bodies.
fn cell_of(v: f64) -> i32 {
    const LIMIT: f64 = (1u64 << 30) as f64;
    let v = v.clamp(-LIMIT, LIMIT);
    let truncated = v as i32;
    truncated - ((truncated as f64) > v) as i32
}

/// Uniform hash grid of body boxes.
#[derive(Debug, Default, Clone)]
pub struct Grid {
    cell_size: f64,
    /// Each cell's entries: each body's index in the low bits and, in the top three, whether
    /// the cell is the lowest of the body's range along x, y and z ([`CellEntry`]). Up to four
    /// are held in the table itself: most cells hold one body, and a `Vec` each (its header and
    /// a heap block) made the grid the largest part of scatter-100000's peak heap.
    cells: CellTable,
    /// Bodies in the grid from which it asks the cache ahead ([`PREFETCH_FROM_BODIES`] from
    /// [`Grid::new`]; tests take both paths).
    hints_from: usize,
    /// Cell range (min, max corner) each body was inserted with; None for oversized bodies
    /// and bodies not in the grid.
    ranges: Vec<Option<(Cell, Cell)>>,
    oversized: Vec<u32>,
    /// Whether each body is in the grid (in cells or oversized).
    present: Vec<bool>,
    stamp: Vec<u32>,
    epoch: u32,
    /// Every pair (i < j, sorted) of bodies in the grid whose boxes overlapped when it was made,
    /// kept from call to call: only the pairs of bodies in `dirty` can have changed since.
    pairs: Vec<(u32, u32)>,
    /// Whether `pairs` is up to date for every body outside `dirty`.
    pairs_valid: bool,
    /// Bodies whose box or presence changed since `pairs` was made, and a flag per body.
    dirty: Vec<u32>,
    is_dirty: Vec<bool>,
}

/// With more than this fraction of the bodies' proxies changed, every crowded cell is walked
/// instead of refreshing the pairs of each changed body (a refresh looks at all entries of the
/// body's cells, the walk at each pair of a cell once). Measured (`bench scale`, broad phase on
/// one thread): always walking cost 2-4x more than refreshing on sparse-1000, pile-1000 and
/// scatter-10000 with either solver; 0.3 and 1.0 were alike there (few steps pass 0.3).
const REFRESH_LIMIT: f64 = 0.3;

/// Bodies in the grid from which [`Grid::sync`] and [`Grid::pairs_of_chunk`] ask the cache
/// ahead. Below, the cells and boxes sit in the caches and the hints only cost instructions:
/// asked for at every size, sparse-1000's step took 11 % more instructions (callgrind) and
/// scatter-10000's was no faster (docs/scale-log.md, "Stop 68").
const PREFETCH_FROM_BODIES: usize = 20_000;

/// Changed bodies ahead of its updates whose cells [`Grid::sync`] asks the cache for.
const SYNC_AHEAD: usize = 4;

/// Dirty bodies between the stages of [`Grid::pairs_of_chunk`].
const STAGE_LAG: usize = 2;

impl Grid {
    /// A grid whose cells are about the size of a typical body.
    pub fn new(cell_size: f64) -> Self {
        Self {
            cell_size: if cell_size.is_finite() && cell_size > 0.0 {
                cell_size
            } else {
                1.0
            },
            hints_from: PREFETCH_FROM_BODIES,
            ..Default::default()
        }
    }

    pub fn cell_size(&self) -> f64 {
        self.cell_size
    }

    /// The cells a box spans (min and max corner), or None for an oversized box. The corners are
    /// clamped to +-2^30 cells, so a body at 1e300 does not loop over billions of cells.
    fn range(&self, aabb: &Aabb) -> Option<(Cell, Cell)> {
        let inv = 1.0 / self.cell_size;
        let (lo, hi) = (aabb.min * inv, aabb.max * inv);
        if !lo.is_finite() || !hi.is_finite() {
            return None;
        }
        let (lo, hi) = (lo.to_array().map(cell_of), hi.to_array().map(cell_of));
        if (0..3).any(|k| hi[k] as i64 - lo[k] as i64 >= MAX_CELLS_PER_AXIS) {
            return None;
        }
        Some((lo, hi))
    }

    fn key(x: i32, y: i32, z: i32) -> u64 {
        // 21 bits per axis: wraps for huge coordinates, which only costs extra box tests.
        let bits = |c: i32| c as u32 as u64 & 0x1F_FFFF;
        (bits(x) << 42) | (bits(y) << 21) | bits(z)
    }

    /// Calls `f` with each cell of `range` (its key) and whether it is the range's lowest along
    /// x, y and z.
    fn for_cells(range: (Cell, Cell), mut f: impl FnMut(u64, [bool; 3])) {
        let (lo, hi) = range;
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    f(Self::key(x, y, z), [x == lo[0], y == lo[1], z == lo[2]]);
                }
            }
        }
    }

    /// Rebuilds the grid from scratch over `aabbs`; bodies with `active[i] == false` are left out.
    pub fn rebuild(&mut self, aabbs: &[Aabb], active: &[bool]) {
        // Cells left empty by the last step are dropped, so the map does not grow with every
        // cell a body ever passed through; the others keep their allocation.
        self.cells.retain(|list| {
            let keep = !list.is_empty();
            list.clear();
            keep
        });
        self.oversized.clear();
        self.ranges.clear();
        self.ranges.resize(aabbs.len(), None);
        self.present.clear();
        self.present.resize(aabbs.len(), false);
        self.stamp.resize(aabbs.len(), 0);
        self.pairs_valid = false;
        self.dirty.clear();
        self.is_dirty.clear();
        self.is_dirty.resize(aabbs.len(), false);
        for (index, aabb) in aabbs.iter().enumerate() {
            if active[index] {
                self.insert(index, aabb);
            }
        }
    }

    /// Brings the grid to `aabbs` (the `active` bodies only) one body at a time: a body whose box
    /// has not `moved` since the last sync costs nothing, one still in the same cells one range
    /// computation, so a scene that mostly stays put is cheap
    /// where [`Grid::rebuild`] would hash every body again. The grid holds the same bodies in
    /// the same cells either way (the lists' order may differ; every query sorts).
    pub fn sync(&mut self, aabbs: &[Aabb], active: &[bool], moved: &[bool]) {
        if self.present.len() != aabbs.len() {
            return self.rebuild(aabbs, active);
        }
        // With many bodies, a second cursor runs [`SYNC_AHEAD`] changed bodies ahead, asking the
        // cache for the slots of their old and new cells, which their update reads.
        let window = if aabbs.len() >= self.hints_from {
            SYNC_AHEAD
        } else {
            0
        };
        let (mut ahead, mut asked) = (0, 0);
        for (index, aabb) in aabbs.iter().enumerate() {
            while asked < window && ahead < aabbs.len() {
                if self.changes(ahead, active, moved) {
                    self.prefetch_cells(ahead, &aabbs[ahead]);
                    asked += 1;
                }
                ahead += 1;
            }
            if !self.changes(index, active, moved) {
                continue;
            }
            // Counted by the cursor ahead, where it runs.
            asked = asked.saturating_sub(1);
            if active[index] {
                self.update(index, aabb);
            } else {
                self.take_out(index);
            }
        }
        // Cells emptied by bodies that moved on are dropped once they outnumber the bodies four
        // to one, so long runs do not grow the table (at 100,000 bodies, 32 MB at most).
        if self.cells.len() > 4 * aabbs.len() + 1024 {
            self.cells.retain(|list| !list.is_empty());
        }
    }

    /// Whether [`Grid::sync`] changes body `index`: moved or new in the grid, or leaving it.
    fn changes(&self, index: usize, active: &[bool], moved: &[bool]) -> bool {
        match active[index] {
            true => moved[index] || !self.present[index],
            false => self.present[index],
        }
    }

    /// Asks the cache for the slots of the cells body `index` is in and of those its new box
    /// `aabb` spans (a hint: nothing changes).
    fn prefetch_cells(&self, index: usize, aabb: &Aabb) {
        let old = self.ranges[index];
        let new = self.range(aabb).filter(|&new| Some(new) != old);
        for range in [old, new].into_iter().flatten() {
            Self::for_cells(range, |key, _| self.cells.prefetch(key));
        }
    }

    /// Notes that body `index`'s pairs must be found again.
    fn mark_dirty(&mut self, index: usize) {
        if !self.is_dirty[index] {
            self.is_dirty[index] = true;
            self.dirty.push(index as u32);
        }
    }

    fn take_out(&mut self, index: usize) {
        self.mark_dirty(index);
        match self.ranges[index] {
            Some(range) => {
                let cells = &mut self.cells;
                Self::for_cells(range, |key, _| {
                    if let Some(list) = cells.get_mut(key) {
                        list.retain(|e| CellEntry(*e).body() as usize != index);
                    }
                });
            }
            None => self.oversized.retain(|&b| b as usize != index),
        }
        self.ranges[index] = None;
        self.present[index] = false;
    }

    fn insert(&mut self, index: usize, aabb: &Aabb) {
        self.mark_dirty(index);
        self.present[index] = true;
        match self.range(aabb) {
            Some(range) => {
                self.ranges[index] = Some(range);
                let cells = &mut self.cells;
                Self::for_cells(range, |key, lowest| {
                    cells.list_mut(key).push(CellEntry::new(index, lowest).0);
                });
            }
            None => self.oversized.push(index as u32),
        }
    }

    /// Moves body `index` to its new box.
    pub fn update(&mut self, index: usize, aabb: &Aabb) {
        // Its box changed even where its cells did not.
        self.mark_dirty(index);
        let new_range = self.range(aabb);
        let old_range = self.ranges[index];
        if new_range.is_some() && new_range == old_range {
            return;
        }
        if self.present[index] {
            self.take_out(index);
        }
        self.insert(index, aabb);
    }

    /// Every pair (i < j) of inserted bodies whose boxes overlap and for which `keep(i, j)`,
    /// sorted, each once. `aabbs` are the boxes the grid was last brought to. The pairs are kept
    /// from call to call and only those of bodies whose boxes changed are found again, unless
    /// so many changed that walking every crowded cell costs less (on all threads either way).
    /// `tested` counts the box comparisons made.
    pub fn overlapping_pairs(
        &mut self,
        aabbs: &[Aabb],
        keep: impl Fn(usize, usize) -> bool + Sync,
        tested: &mut usize,
    ) -> Vec<(u32, u32)> {
        let limit = REFRESH_LIMIT * self.present.len() as f64;
        if !self.pairs_valid || self.dirty.len() as f64 > limit {
            let (pairs, count) = self.walk_crowded_cells(aabbs);
            self.pairs = pairs;
            *tested += count;
        } else {
            *tested += self.refresh_dirty_pairs(aabbs);
        }
        self.pairs_valid = true;
        for &d in &self.dirty {
            self.is_dirty[d as usize] = false;
        }
        self.dirty.clear();
        let wanted = |&(i, j): &(u32, u32)| keep(i as usize, j as usize).then_some((i, j));
        parallel::filter_map(self.pairs.par_iter(), 4096, wanted)
    }

    /// Every pair (i < j, sorted, each once) of bodies in the grid whose boxes overlap. Only
    /// cells holding two bodies or more are visited, in parallel. Returns the pairs and the
    /// number of box tests.
    fn walk_crowded_cells(&self, aabbs: &[Aabb]) -> Found {
        let crowded: Vec<&[u32]> = (self.cells.lists())
            .filter(|list| list.len() > 1)
            .map(|list| list.as_slice())
            .collect();
        let consider = |a: usize, b: usize, found: &mut Found| test_pair(aabbs, a, b, found);
        let in_cells = crowded.par_chunks(64).map(|lists| {
            let mut found = (Vec::new(), 0);
            for list in lists {
                for (k, &a) in list.iter().enumerate() {
                    let a = CellEntry(a);
                    for &b in &list[k + 1..] {
                        let b = CellEntry(b);
                        if a.first_meeting(b) {
                            consider(a.body() as usize, b.body() as usize, &mut found);
                        }
                    }
                }
            }
            found
        });
        let with_oversized = self.oversized.par_iter().map(|&o| {
            let mut found = (Vec::new(), 0);
            for (b, range) in self.ranges.iter().enumerate() {
                if range.is_some() {
                    consider(o as usize, b, &mut found);
                }
            }
            // A pair of two oversized bodies is tested from the lower one.
            for &b in self.oversized.iter().filter(|&&b| b > o) {
                consider(o as usize, b as usize, &mut found);
            }
            found
        });
        merge_found_parts(in_cells, with_oversized)
    }

    /// Brings `pairs` up to date: the pairs of the dirty bodies are dropped and found again from
    /// their cells (in parallel), then merged in. Returns the number of box tests.
    fn refresh_dirty_pairs(&mut self, aabbs: &[Aabb]) -> usize {
        let mut fresh: Vec<Found> = Vec::new();
        parallel::extend_map(&mut fresh, self.dirty.par_chunks(64), 1, |chunk| {
            let mut found = (Vec::new(), 0);
            if self.present.len() >= self.hints_from {
                self.pairs_of_chunk(chunk, aabbs, &mut found);
            } else {
                for &d in chunk.iter().filter(|&&d| self.present[d as usize]) {
                    self.pairs_of(d as usize, aabbs, &mut found);
                }
            }
            found
        });
        let tested = fresh.iter().map(|f| f.1).sum();
        let mut fresh: Vec<(u32, u32)> = fresh.into_iter().flat_map(|f| f.0).collect();
        fresh.par_sort_unstable();
        let is_dirty = &self.is_dirty;
        self.pairs
            .retain(|&(i, j)| !is_dirty[i as usize] && !is_dirty[j as usize]);
        self.pairs = merge_sorted(&self.pairs, &fresh);
        tested
    }

    /// [`Grid::pairs_of`] each body of `chunk` in the grid, with the cache asked ahead in four
    /// stages, each for what the next one reads: for the body's cell range, its cells' slots,
    /// their spilled lists and its partners' boxes, [`STAGE_LAG`] bodies apart. At 100,000
    /// bodies, none of these sit in the caches, and `pairs_of` waited on each in turn.
    fn pairs_of_chunk(&self, chunk: &[u32], aabbs: &[Aabb], found: &mut Found) {
        for i in 0..chunk.len() + 4 * STAGE_LAG {
            let body = |stage: usize| i.checked_sub(stage * STAGE_LAG).and_then(|k| chunk.get(k));
            let range = |stage: usize| body(stage).and_then(|&d| self.ranges[d as usize]);
            if let Some(&d) = body(0) {
                buffer::prefetch(&self.ranges[d as usize]);
            }
            if let Some(range) = range(1) {
                Self::for_cells(range, |key, _| self.cells.prefetch(key));
            }
            if let Some(range) = range(2) {
                Self::for_cells(range, |key, _| {
                    let list = self.cells.get(key);
                    buffer::prefetch_bytes(list.as_ptr().cast(), size_of_val(list));
                });
            }
            if let (Some(&d), Some(range)) = (body(3), range(3)) {
                self.for_each_in_cells(d as usize, range, |b, first_meeting| {
                    if first_meeting {
                        buffer::prefetch(&aabbs[b]);
                    }
                });
            }
            if let Some(&d) = body(4).filter(|&&d| self.present[d as usize]) {
                self.pairs_of(d as usize, aabbs, found);
            }
        }
    }

    /// The pairs of dirty body `d` (in the grid) whose boxes overlap, each found once: a partner
    /// in the cells at the first cell the two share, a dirty partner only from the lower body.
    fn pairs_of(&self, d: usize, aabbs: &[Aabb], found: &mut Found) {
        self.for_each_candidate(d, self.ranges[d], |b, first_meeting| {
            if first_meeting && b != d && (!self.is_dirty[b] || d < b) {
                test_pair(aabbs, d, b, found);
            }
        });
    }

    /// Calls `f(b, first_meeting)` for every body `b` in the grid that may overlap body `index`
    /// spanning `range` (None: oversized, so everyone), and whether this is the first cell the
    /// two share (always, for an oversized side): those who want each pair once keep only that.
    /// `index` itself may come up.
    fn for_each_candidate(
        &self,
        index: usize,
        range: Option<(Cell, Cell)>,
        mut f: impl FnMut(usize, bool),
    ) {
        match range {
            Some(range) => self.for_each_in_cells(index, range, &mut f),
            None => {
                // An oversized body may touch anything.
                for (b, range) in self.ranges.iter().enumerate() {
                    if range.is_some() {
                        f(b, true);
                    }
                }
            }
        }
        for &o in &self.oversized {
            f(o as usize, true);
        }
    }

    /// [`Grid::for_each_candidate`] for a body in cells, the oversized bodies left out.
    fn for_each_in_cells(&self, index: usize, range: (Cell, Cell), mut f: impl FnMut(usize, bool)) {
        Self::for_cells(range, |key, lowest| {
            let me = CellEntry::new(index, lowest);
            for &e in self.cells.get(key) {
                let e = CellEntry(e);
                f(e.body() as usize, me.first_meeting(e));
            }
        });
    }

    /// Bodies (other than `index`) whose boxes overlap `aabbs[index]`, in ascending order.
    pub fn query(&mut self, index: usize, aabbs: &[Aabb], out: &mut Vec<u32>) {
        out.clear();
        self.epoch = self.epoch.wrapping_add(1);
        if self.epoch == 0 {
            self.stamp.iter_mut().for_each(|s| *s = 0);
            self.epoch = 1;
        }
        let aabb = aabbs[index];
        let range = self.ranges[index].or_else(|| self.range(&aabb));
        let (mut stamp, epoch) = (std::mem::take(&mut self.stamp), self.epoch);
        self.for_each_candidate(index, range, |b, _| {
            if b != index && stamp[b] != epoch {
                stamp[b] = epoch;
                if aabbs[b].overlaps(&aabb) {
                    out.push(b as u32);
                }
            }
        });
        self.stamp = stamp;
        out.sort_unstable();
    }
}

/// Two sorted lists without common elements, merged into one sorted list.
fn merge_sorted<T: Copy + Ord>(a: &[T], b: &[T]) -> Vec<T> {
    let mut merged = Vec::with_capacity(a.len() + b.len());
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        if a[i] < b[j] {
            merged.push(a[i]);
            i += 1;
        } else {
            merged.push(b[j]);
            j += 1;
        }
    }
    merged.extend_from_slice(&a[i..]);
    merged.extend_from_slice(&b[j..]);
    merged
}

/// Pairs found by one parallel chunk of a cell walk, and the box tests it made.
type Found = (Vec<(u32, u32)>, usize);

/// The test applied to two bodies that may overlap: counted, and kept (as i < j) when their
/// boxes overlap.
fn test_pair(boxes: &[Aabb], a: usize, b: usize, (pairs, tested): &mut Found) {
    *tested += 1;
    if boxes[a].overlaps(&boxes[b]) {
        pairs.push((a.min(b) as u32, a.max(b) as u32));
    }
}

/// [`merge_found`] over the finds of the cells and of the oversized bodies. Collected one after
/// the other: a chain forks even when one side is empty, and a fork from outside the thread
/// pool wakes a worker and waits for it (tens of microseconds, more than a small scene's step).
fn merge_found_parts(
    in_cells: impl ParallelIterator<Item = Found>,
    with_oversized: impl ParallelIterator<Item = Found>,
) -> Found {
    let mut parts: Vec<Found> = in_cells.collect();
    parts.par_extend(with_oversized);
    merge_found(parts)
}

/// The chunks' pairs, sorted and each once, and their box tests summed.
fn merge_found(chunks: Vec<Found>) -> Found {
    let tested = chunks.iter().map(|c| c.1).sum();
    let mut pairs: Vec<(u32, u32)> = chunks.into_iter().flat_map(|c| c.0).collect();
    // On all threads: a serial sort was the largest part of the step that one thread ran
    // alone at pile-10000 (0.8 % of the samples; the order is total, so the same result).
    pairs.par_sort_unstable();
    pairs.dedup();
    (pairs, tested)
}

/// Cell size for a set of bodies: twice the median diagonal of their boxes, so a typical body's
/// proxy box spans one or two cells per axis (measured on sparse-N and pile-N: 1x costs 2.5x more
/// broad-phase time on sparse-1000, inserting each body into up to 27 cells).
pub fn typical_cell_size(half_extents: impl Iterator<Item = DVec3>) -> f64 {
    let mut sizes: Vec<f64> = half_extents
        .map(|h| 2.0 * h.length())
        .filter(|s| s.is_finite() && *s > 0.0)
        .collect();
    if sizes.is_empty() {
        return 1.0;
    }
    sizes.sort_by(f64::total_cmp);
    2.0 * sizes[sizes.len() / 2]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Boxes of many sizes (a few oversized), some far out where the keys wrap, some NaN, some
    /// bodies left out, moved and synced again body by body: the walk over crowded cells (each
    /// pair reported in the first cell the two share, decided from the cell entries alone)
    /// gives every overlapping pair once, as the test of every pair does.
    #[test]
    fn pairs_match_every_pair_tested_after_moves() {
        let mut rng = crate::sim::rng::Rng::new(777);
        let mut next = move || rng.unit();
        let n = 1200;
        let mut boxes: Vec<Aabb> = (0..n)
            .map(|k: usize| {
                let centre = DVec3::new(next(), next(), next()) * 50.0;
                let half = DVec3::new(next(), next(), next()) * 2.0 + DVec3::splat(0.2);
                let half = if k.is_multiple_of(89) {
                    half * 30.0
                } else {
                    half
                };
                Aabb {
                    min: centre - half,
                    max: centre + half,
                }
            })
            .collect();
        boxes[7] = Aabb {
            min: DVec3::splat(4e6 * 4.0),
            max: DVec3::splat(4e6 * 4.0 + 1.0),
        };
        boxes[8] = Aabb {
            min: DVec3::splat(4e6 * 4.0 + 0.5),
            max: DVec3::splat(4e6 * 4.0 + 2.0),
        };
        boxes[9].max.x = f64::NAN;
        let mut active: Vec<bool> = (0..n).map(|k| k % 17 != 3).collect();
        let keep = |i: usize, j: usize| !(i + j).is_multiple_of(13);
        let expected = |boxes: &[Aabb], active: &[bool]| {
            let mut pairs = Vec::new();
            for i in 0..n {
                for j in i + 1..n {
                    if active[i] && active[j] && boxes[i].overlaps(&boxes[j]) && keep(i, j) {
                        pairs.push((i as u32, j as u32));
                    }
                }
            }
            pairs
        };
        // The same moves on a grid that asks the cache ahead at every size.
        let mut grids = [Grid::new(4.0), Grid::new(4.0)];
        grids[1].hints_from = 0;
        let mut tested = 0;
        for grid in &mut grids {
            grid.sync(&boxes, &active, &vec![true; n]);
            let first = grid.overlapping_pairs(&boxes, keep, &mut tested);
            assert!(first.len() > 1000, "{}", first.len());
            assert_eq!(first, expected(&boxes, &active));
        }
        // Rounds of moves: a third of the bodies (the crowded cells walked again), then a few
        // (their pairs refreshed), some left out and some brought back, and single bodies moved
        // by `update` between syncs, as contacts move them.
        for (round, every) in [3, 40, 9, 200].into_iter().enumerate() {
            let mut moved = vec![false; n];
            for k in (round % every..n).step_by(every) {
                let shift = DVec3::new(next(), next(), next()) * 6.0 - DVec3::splat(3.0);
                boxes[k] = Aabb {
                    min: boxes[k].min + shift,
                    max: boxes[k].max + shift,
                };
                moved[k] = true;
            }
            active
                .iter_mut()
                .enumerate()
                .for_each(|(k, a)| *a = k % 17 != 3 + round);
            let grown: Vec<(usize, f64)> = [11, 500, 89 * 3, 1199]
                .into_iter()
                .filter(|&k| active[k])
                .map(|k| (k, 2.0 * next()))
                .collect();
            let mut moved_boxes = boxes.clone();
            for (g, grid) in grids.iter_mut().enumerate() {
                moved_boxes.clone_from(&boxes);
                grid.sync(&moved_boxes, &active, &moved);
                for &(k, by) in &grown {
                    moved_boxes[k].max += DVec3::splat(by);
                    grid.update(k, &moved_boxes[k]);
                }
                assert_eq!(
                    grid.overlapping_pairs(&moved_boxes, keep, &mut tested),
                    expected(&moved_boxes, &active),
                    "round {round}, grid {g}"
                );
            }
            boxes = moved_boxes;
        }
    }
}
