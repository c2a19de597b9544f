//! The hash table of the broad phase's grid: each occupied cell's key and the bodies in it, in
//! one slot of half a cache line, so that a lookup reads one line and the line can be asked for
//! ahead of the lookup ([`CellTable::prefetch`]). At 100,000 bodies the grid's cells are far
//! more than the caches hold, and a refresh of the pairs of the bodies that moved waited on
//! each lookup in turn (std's table reads a control line and a bucket line, and nothing can
//! ask for them ahead).
//!
//! Open addressing with linear probing (Knuth, TAOCP vol. 3, 6.4, algorithm L), filled to at
//! most three quarters: with probing, a lookup usually ends in the line it starts in.

use smallvec::SmallVec;

/// The bodies in one cell (their [`super::grid`] entries). Up to four are held in the slot
/// itself: most cells hold one body.
pub type CellList = SmallVec<[u32; 4]>;

/// A slot's key when it holds no cell: cell keys take 63 bits.
const VACANT: u64 = u64::MAX;

/// One cell. Aligned to 32 bytes, its size (with smallvec's `union`), so that no slot
/// straddles two cache lines.
#[derive(Clone, Debug)]
#[repr(align(32))]
struct Slot {
    key: u64,
    list: CellList,
}

const _: () = assert!(std::mem::size_of::<Slot>() == 32);

/// The hash of a cell key (the grid's keys: x, y and z in 21 bits each, z lowest): all but the
/// lowest bit mixed by MurmurHash3's finaliser, shifted up, and that bit kept, so that the two
/// cells z = 2k and 2k + 1 of one (x, y), which a body often spans both of (its cells are walked
/// z fastest), have neighbouring slots. Deterministic across runs. The z cell added unmixed, as
/// the grid's hasher did for std's table, made runs of hundreds of slots under linear probing
/// (scatter-100000's rows of bodies along z).
fn cell_hash(key: u64) -> u64 {
    let mut h = key >> 1;
    h ^= h >> 33;
    h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
    h ^= h >> 33;
    h << 1 | (key & 1)
}

impl Slot {
    fn vacant() -> Self {
        Self {
            key: VACANT,
            list: CellList::new(),
        }
    }
}

/// A map from cell keys to the bodies in them. A cell once made stays, its list maybe empty,
/// until [`CellTable::retain`] drops it: probing needs no marks for removed keys.
#[derive(Clone, Debug, Default)]
pub struct CellTable {
    /// A power of two of slots, or none.
    slots: Vec<Slot>,
    /// Slots holding a cell.
    len: usize,
}

/// Slots in the smallest table.
const MIN_SLOTS: usize = 16;

impl CellTable {
    /// Cells held (their lists maybe empty).
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether no cell is held.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The bodies in cell `key` (none where it is not held).
    pub fn get(&self, key: u64) -> &[u32] {
        match self.find(key) {
            Ok(slot) => &self.slots[slot].list,
            Err(_) => &[],
        }
    }

    /// Cell `key`'s list, where it is held.
    pub fn get_mut(&mut self, key: u64) -> Option<&mut CellList> {
        let slot = self.find(key).ok()?;
        Some(&mut self.slots[slot].list)
    }

    /// Cell `key`'s list, made empty where it was not held.
    pub fn list_mut(&mut self, key: u64) -> &mut CellList {
        let mut found = self.find(key);
        if found.is_err() && (self.len + 1) * 4 > self.slots.len() * 3 {
            self.grow();
            found = self.find(key);
        }
        let slot = found.unwrap_or_else(|vacant| {
            self.slots[vacant].key = key;
            self.len += 1;
            vacant
        });
        &mut self.slots[slot].list
    }

    /// Asks the cache for the line where a lookup of `key` starts (a hint: nothing changes).
    #[inline(always)]
    pub fn prefetch(&self, key: u64) {
        if !self.slots.is_empty() {
            super::buffer::prefetch(&self.slots[self.home(key)]);
        }
    }

    /// The lists of the cells held, in slot order.
    pub fn lists(&self) -> impl Iterator<Item = &CellList> {
        self.slots
            .iter()
            .filter(|s| s.key != VACANT)
            .map(|s| &s.list)
    }

    /// Keeps the cells whose lists `keep` (which may change them) says to keep, in a table sized
    /// for them.
    pub fn retain(&mut self, keep: impl FnMut(&mut CellList) -> bool) {
        let kept = self.take_held(keep);
        let mut size = MIN_SLOTS;
        while kept.len() * 4 > size * 3 {
            size *= 2;
        }
        self.place(kept, size);
    }

    /// The slot where a lookup of `key` starts: [`cell_hash`] masked to the table's size.
    fn home(&self, key: u64) -> usize {
        cell_hash(key) as usize & (self.slots.len() - 1)
    }

    /// The slot holding `key`, or the vacant slot where it would go.
    fn find(&self, key: u64) -> Result<usize, usize> {
        if self.slots.is_empty() {
            return Err(0);
        }
        let mask = self.slots.len() - 1;
        let mut slot = self.home(key);
        loop {
            match self.slots[slot].key {
                k if k == key => return Ok(slot),
                VACANT => return Err(slot),
                _ => slot = (slot + 1) & mask,
            }
        }
    }

    /// Twice the slots, every cell placed again.
    fn grow(&mut self) {
        let size = (2 * self.slots.len()).max(MIN_SLOTS);
        let held = self.take_held(|_| true);
        self.place(held, size);
    }

    /// The cells held whose lists `keep` says to keep, the table left without slots.
    fn take_held(&mut self, mut keep: impl FnMut(&mut CellList) -> bool) -> Vec<Slot> {
        std::mem::take(&mut self.slots)
            .into_iter()
            .filter_map(|mut s| (s.key != VACANT && keep(&mut s.list)).then_some(s))
            .collect()
    }

    /// `size` slots (a power of two) holding the cells `held`.
    fn place(&mut self, held: Vec<Slot>, size: usize) {
        self.slots = vec![Slot::vacant(); size];
        self.len = held.len();
        for s in held {
            let vacant = self.find(s.key).expect_err("a key is held once");
            self.slots[vacant] = s;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    /// Cells made, filled, emptied and dropped in many rounds give what std's map gives, key for
    /// key, across the table's growth and its shrinking by `retain`.
    #[test]
    fn lists_match_std_maps() {
        let mut rng = crate::sim::rng::Rng::new(5);
        let mut table = CellTable::default();
        let mut map: HashMap<u64, Vec<u32>> = HashMap::new();
        assert!(table.is_empty() && table.get(3).is_empty() && table.get_mut(3).is_none());
        for round in 0..6 {
            let keys = 300 + 2000 * (round % 3);
            for k in 0..keys {
                // Runs of neighbouring z keys, as a body's cells make, and keys far apart.
                let key = ((rng.unit() * 50.0) as u64) << 42 | (k as u64 % 97) << 21 | k as u64;
                let body = (rng.unit() * 1e6) as u32;
                table.list_mut(key).push(body);
                map.entry(key).or_default().push(body);
            }
            for (k, (key, list)) in map.iter_mut().enumerate() {
                if k % 3 == round % 3 {
                    list.clear();
                    table.get_mut(*key).unwrap().clear();
                }
            }
            assert_eq!(table.len(), map.len(), "round {round}");
            for (key, list) in &map {
                assert_eq!(table.get(*key), &list[..], "round {round}");
            }
            let mut lists: Vec<Vec<u32>> = table.lists().map(|l| l.to_vec()).collect();
            let mut expected: Vec<Vec<u32>> = map.values().cloned().collect();
            lists.sort();
            expected.sort();
            assert_eq!(lists, expected, "round {round}");
            table.retain(|l| !l.is_empty());
            map.retain(|_, l| !l.is_empty());
            assert_eq!(table.len(), map.len(), "round {round}");
            assert!(table.slots.len() * 3 >= table.len * 4, "round {round}");
        }
    }
}
