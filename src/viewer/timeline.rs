//! Rewind: the complete state of every compared world after each step (poses, velocities, time,
//! and what the solvers carry between steps), in a ring bounded by memory. Restoring an entry
//! repeats the later steps bit for bit ([`World::restore`]); one entry holds the states of all
//! the session's worlds at the same tick, so compared worlds rewind in lockstep.

use crate::World;
use crate::sim::WorldState;
use std::collections::VecDeque;

/// Default memory budget of the history.
pub const DEFAULT_BUDGET: usize = 256 << 20;

/// The states of all worlds after one tick.
struct Entry {
    states: Vec<WorldState>,
    bytes: usize,
}

impl Entry {
    fn of<'a>(worlds: impl Iterator<Item = &'a World>) -> Entry {
        Entry::of_states(worlds.map(World::snapshot).collect())
    }

    fn of_states(states: Vec<WorldState>) -> Entry {
        let bytes = std::mem::size_of::<Entry>()
            + states
                .iter()
                .map(|s| s.heap_bytes() + std::mem::size_of::<WorldState>())
                .sum::<usize>();
        Entry { states, bytes }
    }
}

/// What the history covers, for the panel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Span {
    pub first_step: u64,
    pub last_step: u64,
    pub seconds: f64,
    pub bytes: usize,
}

pub struct Timeline {
    entries: VecDeque<Entry>,
    bytes: usize,
    /// Most bytes the entries may hold; the oldest go first. The cursor's entry is always kept.
    budget: usize,
    /// Index of the entry the worlds are at.
    cursor: usize,
}

impl Timeline {
    pub fn new(budget: usize) -> Timeline {
        Timeline {
            entries: VecDeque::new(),
            bytes: 0,
            budget,
            cursor: 0,
        }
    }

    pub fn clear(&mut self) {
        self.entries.clear();
        self.bytes = 0;
        self.cursor = 0;
    }

    pub fn len(&self) -> usize {
        self.entries.len()
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Index of the entry the worlds are at.
    pub fn cursor(&self) -> usize {
        self.cursor
    }

    /// Whether the worlds are at the newest entry (not in the past).
    pub fn at_end(&self) -> bool {
        self.cursor + 1 >= self.entries.len()
    }

    pub fn budget(&self) -> usize {
        self.budget
    }

    /// Changes the memory budget, dropping the oldest entries that no longer fit.
    pub fn set_budget(&mut self, bytes: usize) {
        self.budget = bytes;
        self.evict();
    }

    /// Appends the worlds' states after the cursor; entries after the cursor (a past state
    /// resumed from) are dropped first.
    pub fn record<'a>(&mut self, worlds: impl Iterator<Item = &'a World>) {
        self.truncate_after_cursor();
        let entry = Entry::of(worlds);
        self.bytes += entry.bytes;
        self.entries.push_back(entry);
        self.cursor = self.entries.len() - 1;
        self.evict();
    }

    /// The worlds at the cursor were edited (a body moved while paused): the entry becomes their
    /// new state and the entries after it, which no longer follow from it, are dropped.
    pub fn replace_current<'a>(&mut self, worlds: impl Iterator<Item = &'a World>) {
        self.truncate_after_cursor();
        if let Some(old) = self.entries.pop_back() {
            self.bytes -= old.bytes;
        }
        self.record(worlds);
    }

    /// Keeps the states of the first `lanes` worlds in every entry (a comparison ended).
    pub fn keep_lanes(&mut self, lanes: usize) {
        for entry in &mut self.entries {
            entry.states.truncate(lanes);
            *entry = Entry::of_states(std::mem::take(&mut entry.states));
        }
        self.bytes = self.entries.iter().map(|e| e.bytes).sum();
    }

    /// Moves the cursor to entry `index` (clamped) and returns the states to restore.
    pub fn seek(&mut self, index: usize) -> Option<&[WorldState]> {
        if self.entries.is_empty() {
            return None;
        }
        self.cursor = index.min(self.entries.len() - 1);
        Some(&self.entries[self.cursor].states)
    }

    /// The index of the entry at step `step` of the first world, if it is still kept.
    pub fn index_of_step(&self, step: u64) -> Option<usize> {
        let first = self.entries.front()?.states.first()?.step_count();
        let index = usize::try_from(step.checked_sub(first)?).ok()?;
        (index < self.entries.len()).then_some(index)
    }

    /// Step count of the first world at entry `index`.
    pub fn step_at(&self, index: usize) -> Option<u64> {
        Some(self.entries.get(index)?.states.first()?.step_count())
    }

    pub fn span(&self) -> Span {
        let state = |e: Option<&Entry>| e.and_then(|e| e.states.first().cloned());
        match (state(self.entries.front()), state(self.entries.back())) {
            (Some(first), Some(last)) => Span {
                first_step: first.step_count(),
                last_step: last.step_count(),
                seconds: last.time() - first.time(),
                bytes: self.bytes,
            },
            _ => Span {
                first_step: 0,
                last_step: 0,
                seconds: 0.0,
                bytes: 0,
            },
        }
    }

    fn truncate_after_cursor(&mut self) {
        while self.entries.len() > self.cursor + 1 {
            let dropped = self.entries.pop_back().expect("longer than the cursor");
            self.bytes -= dropped.bytes;
        }
    }

    /// Drops entries until the rest fit the budget, never the one the worlds are at: the oldest
    /// first, then, rewound to the oldest left, the newest. (Dropping the cursor's own entry
    /// left the cursor on a later state than the worlds', and resuming wrote a history out of
    /// order.)
    fn evict(&mut self) {
        while self.bytes > self.budget && self.entries.len() > 1 {
            let dropped = if self.cursor > 0 {
                self.cursor -= 1;
                self.entries.pop_front()
            } else {
                self.entries.pop_back()
            };
            self.bytes -= dropped.expect("more than one entry").bytes;
        }
    }
}
