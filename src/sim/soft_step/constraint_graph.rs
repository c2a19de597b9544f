//! Graph colouring of the contact constraints (after Box2D v3's constraint graph): the
//! manifolds are put in an order where each colour is a run of constraints no two of which
//! share a moving body, so a colour's constraints can be solved at once on several threads.
//! Colours run one after another, always in the same order, so the result is the same bits
//! on any number of threads: the colouring, not the scheduling, fixes the Gauss-Seidel order.

use super::manifold::{GROUND, Manifold};
use super::solver_body::SolverBody;
use crate::sim::parallel;
use rayon::prelude::*;
use std::marker::PhantomData;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// Colours tried before a constraint goes to the overflow run (solved alone, last).
const COLOURS: usize = 64;

/// Runs of the (reordered) manifolds, one per colour, the overflow last.
#[derive(Debug, Clone, Default)]
pub struct Colours {
    runs: Vec<Range<usize>>,
    /// Whether the last run is the overflow (its constraints may share bodies).
    overflow: bool,
    /// Scratch: each body's used colours, each manifold's colour and its place in colour order.
    used: Vec<u64>,
    colour_of: Vec<u8>,
    place: Vec<u32>,
}

impl Colours {
    /// Colours `manifolds` greedily in their order (each takes the lowest colour neither of its
    /// moving bodies has) and reorders them by colour, keeping their order within a colour.
    /// `bodies` is the number of bodies; `moving(i)` says whether the solver moves body `i`.
    pub fn colour(
        &mut self,
        manifolds: &mut [Manifold],
        bodies: usize,
        moving: impl Fn(usize) -> bool,
    ) {
        self.colour_of.clear();
        if manifolds.is_empty() {
            // (A chain or a body in flight: no contact, and no per-colour pass to make.)
            self.runs.clear();
            self.overflow = false;
            return;
        }
        self.used.clear();
        self.used.resize(bodies, 0);
        let mut counts = [0usize; COLOURS + 1];
        for m in manifolds.iter() {
            let movers = [m.body1, m.body2].map(|i| (i != GROUND && moving(i)).then_some(i));
            let taken = movers.iter().flatten().fold(0u64, |t, &i| t | self.used[i]);
            let colour = (taken.trailing_ones() as usize).min(COLOURS);
            if colour < COLOURS {
                for &i in movers.iter().flatten() {
                    self.used[i] |= 1 << colour;
                }
            }
            self.colour_of.push(colour as u8);
            counts[colour] += 1;
        }
        self.runs.clear();
        let mut start = 0;
        for &count in counts.iter().filter(|&&c| c > 0) {
            self.runs.push(start..start + count);
            start += count;
        }
        self.overflow = counts[COLOURS] > 0;
        self.reorder(manifolds, &counts);
    }

    /// `len` constraints in one run, solved in their order on one thread, as the overflow run
    /// is: a batch of small islands copied out of the step's (see [`super::island_batch`]),
    /// in the colouring's order.
    pub fn sequential(&mut self, len: usize) {
        self.runs.clear();
        self.runs.extend((len > 0).then_some(0..len));
        self.overflow = len > 0;
    }

    /// Stable counting sort of the manifolds by colour, in place: each manifold's place is
    /// counted first, then the permutation is applied cycle by cycle (4 bytes of scratch per
    /// manifold instead of a second copy of them).
    fn reorder(&mut self, manifolds: &mut [Manifold], counts: &[usize; COLOURS + 1]) {
        let mut next = [0u32; COLOURS + 1];
        for c in 1..=COLOURS {
            next[c] = next[c - 1] + counts[c - 1] as u32;
        }
        self.place.clear();
        self.place.extend(self.colour_of.iter().map(|&colour| {
            let place = next[colour as usize];
            next[colour as usize] += 1;
            place
        }));
        for i in 0..manifolds.len() {
            while self.place[i] as usize != i {
                let to = self.place[i] as usize;
                manifolds.swap(i, to);
                self.place.swap(i, to);
            }
        }
    }

    /// Runs `f` on every constraint, colour after colour (the constraints are in colour order,
    /// like the manifolds they were made from); see [`Colours::run`]. `f` may touch only its
    /// constraint's bodies and points. `ahead` is shown the constraint `AHEAD` places further
    /// on in the same thread's share before each call of `f`, to ask the cache for what it will
    /// read ([`Shared::prefetch`]); it changes nothing.
    pub fn for_each<C: Send>(
        &self,
        constraints: &mut [C],
        ahead: impl Fn(&C) + Sync,
        f: impl Fn(&mut C) + Sync,
    ) {
        let shared = Shared::new(constraints);
        let runs = &self.runs;
        // SAFETY: each constraint is one run's, and `run` hands each place of a run to one call.
        let each = |k: usize, places: Range<usize>| {
            let start = runs[k].start;
            let slice = unsafe { shared.slice(start + places.start..start + places.end) };
            for i in 0..slice.len() {
                if let Some(later) = slice.get(i + AHEAD) {
                    ahead(later);
                }
                f(&mut slice[i]);
            }
        };
        self.run(|k| runs[k].len(), PARALLEL_PASS, each);
    }

    /// [`Colours::for_each`] on the constraints at `selected` (strictly increasing indices)
    /// only: the same order, so the same result as running `f` on them one by one.
    pub fn for_each_selected<C: Send>(
        &self,
        constraints: &mut [C],
        selected: &[u32],
        ahead: impl Fn(&C) + Sync,
        f: impl Fn(&mut C) + Sync,
    ) {
        self.for_each_selected_from(constraints, (selected, PARALLEL_PASS), ahead, f);
    }

    /// [`Colours::for_each_selected`], on all threads only from `parallel_from` constraints up
    /// (a pass lighter per constraint than a solve pays for the barriers later).
    pub fn for_each_selected_from<C: Send>(
        &self,
        constraints: &mut [C],
        (selected, parallel_from): (&[u32], usize),
        ahead: impl Fn(&C) + Sync,
        f: impl Fn(&mut C) + Sync,
    ) {
        assert!(
            selected.windows(2).all(|w| w[0] < w[1]),
            "selection not increasing"
        );
        let bounds: Vec<usize> = (self.runs.iter())
            .map(|run| selected.partition_point(|&i| (i as usize) < run.start))
            .chain(std::iter::once(selected.len()))
            .collect();
        let shared = Shared::new(constraints);
        // SAFETY: the indices are distinct, so each constraint has one user.
        let each = |k: usize, places: Range<usize>| {
            let chosen = &selected[bounds[k] + places.start..bounds[k] + places.end];
            for (n, &i) in chosen.iter().enumerate() {
                if let Some(&later) = chosen.get(n + AHEAD) {
                    // SAFETY: a later constraint of this share, which no other thread touches.
                    ahead(unsafe { shared.get(later as usize) });
                }
                f(unsafe { shared.get_mut(i as usize) });
            }
        };
        self.run(|k| bounds[k + 1] - bounds[k], parallel_from, each);
    }

    /// Calls `each(k, places)` over the places `0..len(k)` of every run `k`, run after run. With
    /// several threads and enough to do, every thread of the pool takes an equal share of each
    /// colour and waits for the others at a barrier before the next ([`ColourBarrier`]); the
    /// overflow run, whose constraints may share bodies, goes on one thread at the end. A
    /// colour's constraints share no moving body, so the shares give the bits of one thread.
    ///
    /// One broadcast per pass, not a fork per colour: a manifold's pass takes about 0.2 us, and
    /// a fork wakes a sleeping worker and waits for it, about 10 us here, more than a small
    /// colour takes. Forked per colour, colours under 256 manifolds ran on one thread (pile-200
    /// at dt 0.04 took 0.42-0.56 s for 250 steps that way, 0.60-0.74 with 64), which was every
    /// colour of a pile of a few hundred bodies; with the broadcast the soft step's solve stage
    /// of pile-200 (dt 0.02, 500 steps) takes 0.20 against 0.26 ms a step on two threads, and
    /// pile-1000's 0.95 against 1.28.
    fn run(
        &self,
        len: impl Fn(usize) -> usize + Sync,
        parallel_from: usize,
        each: impl Fn(usize, Range<usize>) + Sync,
    ) {
        if self.runs.is_empty() {
            return;
        }
        let alone = self.runs.len() - usize::from(self.overflow);
        let total: usize = (0..alone).map(&len).sum();
        // (Asked only when there is enough to share: asking costs a small scene's pass more
        // than the pass, a free body's step 8 % of its time.)
        let threads = match total >= parallel_from {
            true => rayon::current_num_threads(),
            false => 1,
        };
        if threads < 2 {
            (0..alone).for_each(|k| each(k, 0..len(k)));
        } else {
            let barrier = ColourBarrier::new(threads);
            rayon::broadcast(|ctx| {
                let (t, n) = (ctx.index(), ctx.num_threads());
                let _release = barrier.released_on_panic();
                for k in 0..alone {
                    let count = len(k);
                    each(k, count * t / n..count * (t + 1) / n);
                    barrier.wait();
                }
            });
        }
        if alone < self.runs.len() {
            each(alone, 0..len(alone));
        }
    }
}

/// How many constraints ahead [`Colours::for_each`] shows its `ahead` hook: far enough that the
/// bodies asked for arrive before their constraint's turn (a manifold's pass takes 0.05-0.2 us,
/// a miss to memory about 0.1 us).
const AHEAD: usize = 4;

/// Passes over fewer constraints than this run on one thread: the broadcast and a barrier per
/// colour cost microseconds, as much as a pass of a few dozen manifolds.
const PARALLEL_PASS: usize = 64;

/// A barrier for the threads of one broadcast: each waits until all have arrived, yielding its
/// core meanwhile: the colours between barriers take microseconds, less than a sleep and a
/// wake-up, and a core shared with other work (three simulations at once on two cores) is
/// handed over. Spinning instead of yielding took that case from 2.0-2.1 to 2.2-2.6 s
/// (three runs of pile-1000 at once, 300 steps each), yielding to 2.2; one run alone is as
/// fast either way. A thread that panics opens it for good, so the others finish and the
/// broadcast passes the panic on instead of hanging.
struct ColourBarrier {
    threads: usize,
    arrived: AtomicUsize,
    generation: AtomicUsize,
    open: AtomicBool,
}

impl ColourBarrier {
    fn new(threads: usize) -> Self {
        Self {
            threads,
            arrived: AtomicUsize::new(0),
            generation: AtomicUsize::new(0),
            open: AtomicBool::new(false),
        }
    }

    fn wait(&self) {
        let generation = self.generation.load(Ordering::Acquire);
        if self.arrived.fetch_add(1, Ordering::AcqRel) + 1 == self.threads {
            self.arrived.store(0, Ordering::Relaxed);
            self.generation.fetch_add(1, Ordering::Release);
            return;
        }
        while self.generation.load(Ordering::Acquire) == generation
            && !self.open.load(Ordering::Acquire)
        {
            std::thread::yield_now();
        }
    }

    /// A guard that opens the barrier if its thread unwinds.
    fn released_on_panic(&self) -> impl Drop + '_ {
        struct Release<'a>(&'a AtomicBool);
        impl Drop for Release<'_> {
            fn drop(&mut self) {
                if std::thread::panicking() {
                    self.0.store(true, Ordering::Release);
                }
            }
        }
        Release(&self.open)
    }
}

/// The solver bodies and contact points, shared by the threads solving one colour (or the
/// joint groups). Within a colour no two constraints share a moving body or a point, and no two
/// joint groups share a moving body; bodies that do not move (the ground, fixed and sleeping
/// bodies) are shared but only read.
pub struct Shared<'a, T> {
    ptr: *mut T,
    len: usize,
    _borrow: PhantomData<&'a mut [T]>,
}

// SAFETY: access goes through the methods below, whose callers uphold the colouring's
// disjointness (see the type's documentation).
unsafe impl<T: Send> Sync for Shared<'_, T> {}

impl<'a, T> Shared<'a, T> {
    pub fn new(slice: &'a mut [T]) -> Self {
        Self {
            ptr: slice.as_mut_ptr(),
            len: slice.len(),
            _borrow: PhantomData,
        }
    }
}

impl<T: Copy> Shared<'_, T> {
    /// A copy of element `i`.
    ///
    /// # Safety
    /// No other thread writes element `i` meanwhile.
    pub unsafe fn read(&self, i: usize) -> T {
        assert!(i < self.len);
        // SAFETY: in bounds; no concurrent writer by the caller's contract.
        unsafe { self.ptr.add(i).read() }
    }

    /// Writes element `i`.
    ///
    /// # Safety
    /// No other thread reads or writes element `i` meanwhile.
    pub unsafe fn write(&self, i: usize, value: T) {
        assert!(i < self.len);
        // SAFETY: in bounds; exclusive by the caller's contract.
        unsafe { self.ptr.add(i).write(value) }
    }
}

impl<T> Shared<'_, T> {
    /// Element `i`.
    ///
    /// # Safety
    /// No other thread writes element `i` meanwhile.
    pub unsafe fn get(&self, i: usize) -> &T {
        assert!(i < self.len);
        // SAFETY: in bounds; no concurrent writer by the caller's contract.
        unsafe { &*self.ptr.add(i) }
    }

    /// Element `i`, mutably.
    ///
    /// # Safety
    /// No other thread touches element `i` meanwhile.
    #[allow(clippy::mut_from_ref)]
    pub unsafe fn get_mut(&self, i: usize) -> &mut T {
        assert!(i < self.len);
        // SAFETY: in bounds; exclusive by the caller's contract.
        unsafe { &mut *self.ptr.add(i) }
    }

    /// Asks the cache for element `i`'s lines: a hint, nothing is read or written (and nothing
    /// happens off x86-64 or out of bounds).
    #[inline(always)]
    pub fn prefetch(&self, i: usize) {
        if i < self.len {
            crate::sim::buffer::prefetch(self.ptr.wrapping_add(i));
        }
    }

    /// Elements `range`, mutably.
    ///
    /// # Safety
    /// No other thread touches these elements meanwhile.
    #[allow(clippy::mut_from_ref)]
    pub unsafe fn slice(&self, range: Range<usize>) -> &mut [T] {
        assert!(range.start <= range.end && range.end <= self.len);
        // SAFETY: in bounds; exclusive by the caller's contract.
        unsafe { std::slice::from_raw_parts_mut(self.ptr.add(range.start), range.len()) }
    }
}

/// Runs `f(i, &mut a[i])` for every index in `indices` (strictly increasing), on all threads:
/// each element is touched by one call only, so the result does not depend on the schedule.
pub fn for_each_indexed<A: Send>(indices: &[usize], a: &mut [A], f: impl Fn(usize, &mut A) + Sync) {
    assert!(
        indices.windows(2).all(|w| w[0] < w[1]),
        "indices not increasing"
    );
    assert!(indices.last().is_none_or(|&last| last < a.len()));
    let a = Shared::new(a);
    // SAFETY: the indices are distinct, so each element has one user.
    let each = |&i: &usize| f(i, unsafe { a.get_mut(i) });
    parallel::for_each(indices.par_iter(), PARALLEL_INDICES, each);
}

/// Fewest indices [`for_each_indexed`] shares among threads.
const PARALLEL_INDICES: usize = 256;

/// [`for_each_indexed`] over two arrays: `f(i, &mut a[i], &mut b[i])`.
pub fn for_each_indexed2<A: Send, B: Send>(
    indices: &[usize],
    a: &mut [A],
    b: &mut [B],
    f: impl Fn(usize, &mut A, &mut B) + Sync,
) {
    assert!(indices.last().is_none_or(|&last| last < b.len()));
    let b = Shared::new(b);
    // SAFETY: `for_each_indexed` calls once per distinct index.
    for_each_indexed(indices, a, |i, x| f(i, x, unsafe { b.get_mut(i) }));
}

/// Runs `solve` on a constraint's two solver bodies: the moving ones in place, the others
/// (the ground, fixed and sleeping bodies) on copies, so constraints of one colour may share
/// them.
///
/// # Safety
/// Within the running colour, no other constraint touches `i` or `j` if they move.
pub unsafe fn with_pair<R>(
    bodies: &Shared<SolverBody>,
    (i, j): (usize, usize),
    solve: impl FnOnce(&mut SolverBody, &mut SolverBody) -> R,
) -> R {
    // SAFETY: the caller's contract: moving bodies are this constraint's alone, and the others
    // are never written while a colour runs.
    // Only the static ones are copied: a solver body is 184 bytes, and copying both took 5 % of
    // pile-10000's step.
    unsafe {
        let (mut copy1, mut copy2);
        let b1 = if bodies.get(i).inverse_mass > 0.0 {
            bodies.get_mut(i)
        } else {
            copy1 = bodies.read(i);
            &mut copy1
        };
        let b2 = if bodies.get(j).inverse_mass > 0.0 {
            bodies.get_mut(j)
        } else {
            copy2 = bodies.read(j);
            &mut copy2
        };
        solve(b1, b2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::rng::Rng;
    use glam::DVec3;

    /// A constraint's step on one of its moving bodies' values: order-dependent, so any
    /// constraint run out of Gauss-Seidel order, twice, or not at all changes the result.
    fn solve(value: &mut f64, k: usize) {
        *value = *value * 1.000_000_1 + k as f64;
    }

    /// Colour by colour, each colour shared among the threads, gives the bits of one pass in
    /// order, over all constraints and over a selection of them, on two threads and on three.
    #[test]
    fn colours_run_constraints_as_one_pass_in_order_would() {
        let (bodies, count) = (3000, 12_000);
        let mut rng = Rng::new(11);
        let mut below = |n: usize| (rng.next_u64() % n as u64) as usize;
        let moving: Vec<bool> = (0..bodies).map(|i| i % 17 != 0).collect();
        // Some on the ground, and a body in 400, more than there are colours: an overflow run.
        let mut manifolds: Vec<Manifold> = (0..count)
            .map(|k| {
                let i = if k % 30 == 0 { 1 } else { below(bodies) };
                let j = (i + 1 + below(bodies - 1)) % bodies;
                let (i, j) = if below(10) == 0 { (GROUND, j) } else { (i, j) };
                Manifold::new(i, j, DVec3::Y, &[])
            })
            .collect();
        let mut colours = Colours::default();
        colours.colour(&mut manifolds, bodies, |i| moving[i]);
        assert!(colours.runs.len() > 10 && count >= 100 * PARALLEL_PASS);
        assert!(colours.overflow && colours.runs.last().unwrap().len() >= 2);
        let ends = |k: usize| [manifolds[k].body1, manifolds[k].body2];
        let moved = |b: &usize| *b != GROUND && moving[*b];
        let mut constraints: Vec<usize> = (0..count).collect();
        let selected: Vec<u32> = (0..count as u32).filter(|k| k % 3 != 1).collect();
        let run = |selection: Option<&[u32]>, constraints: &mut [usize], threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut values = vec![1.0; bodies];
            let shared = Shared::new(&mut values);
            // SAFETY: within a colour no two constraints share a moving body, and only moving
            // bodies are written.
            let each = |&mut k: &mut usize| {
                (ends(k).iter().filter(|b| moved(b)))
                    .for_each(|&b| solve(unsafe { shared.get_mut(b) }, k))
            };
            pool.install(|| match selection {
                Some(selected) => colours.for_each_selected(constraints, selected, |_| {}, each),
                None => colours.for_each(constraints, |_| {}, each),
            });
            values
        };
        let in_order = |chosen: &mut dyn Iterator<Item = usize>| {
            let mut values = vec![1.0; bodies];
            for k in chosen {
                (ends(k).iter().filter(|b| moved(b))).for_each(|&b| solve(&mut values[b], k));
            }
            values
        };
        let all = in_order(&mut (0..count));
        let some = in_order(&mut selected.iter().map(|&k| k as usize));
        assert!(all != some);
        for threads in [2, 3] {
            assert!(run(None, &mut constraints, threads) == all);
            assert!(run(Some(&selected), &mut constraints, threads) == some);
        }
    }

    /// A constraint that panics on one thread of a shared colour ends the pass with the panic,
    /// not with the other threads waiting for it at the colour's barrier.
    #[test]
    fn a_panic_in_a_shared_colour_is_passed_on() {
        let (bodies, count) = (500, 2_000);
        let mut manifolds: Vec<Manifold> = (0..count)
            .map(|k| Manifold::new(k % bodies, (k * 7 + 1) % bodies, DVec3::Y, &[]))
            .collect();
        let mut colours = Colours::default();
        colours.colour(&mut manifolds, bodies, |_| true);
        let mut constraints: Vec<usize> = (0..count).collect();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            pool.install(|| {
                colours.for_each(
                    &mut constraints,
                    |_| {},
                    |&mut k| assert!(k != 777, "constraint 777"),
                );
            })
        }));
        assert!(outcome.is_err());
    }
}
