//! Passes over the bodies or constraints that go to the thread pool only when they are long.
//!
//! rayon's set-up for a pass (asking the pool for its size, splitting, the consumer chain) costs
//! several hundred instructions even when it hands nothing over, and a one-body step makes a
//! dozen passes: 16,000 instructions a step for a free body under the soft step, a fifth of them
//! rayon's (callgrind). Below twice its `min` a pass would not be split anyway, so it runs the
//! same items in the same order on this thread, through the iterator's own sequential form
//! (`with_producer`): the results are the same bits either way.

use rayon::iter::plumbing::{Producer, ProducerCallback};
use rayon::prelude::*;

/// Runs `f` on a thread of rayon's pool, or right here when already on one. Each hand-over
/// wakes an idle core: on a 2-core virtual machine an empty one took 40-105 us (one thread or
/// two, the pool idle for 0-1000 us before), a sixth of a pile-200 step under the soft step;
/// hence [`crate::World::stepping`] for loops of steps.
pub fn in_pool<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    match rayon::current_thread_index() {
        Some(_) => f(),
        None => rayon::scope(|_| f()),
    }
}

/// Whether a pass of `len` items with runs of at least `min` stays on this thread: rayon would
/// not split fewer than two runs.
fn on_this_thread(len: usize, min: usize) -> bool {
    len < 2 * min.max(1)
}

/// Calls `f` on every item of `items`: on this thread when there are fewer than twice `min`,
/// else shared among the pool's threads in runs of at least `min`.
pub fn for_each<I>(items: I, min: usize, f: impl Fn(I::Item) + Sync + Send)
where
    I: IndexedParallelIterator,
{
    if on_this_thread(items.len(), min) {
        items.with_producer(ForEach(f))
    } else {
        items.with_min_len(min).for_each(f)
    }
}

/// Appends `f(item)` to `out` for every item, in the items' order; on this thread or the pool by
/// the rule of [`for_each`].
pub fn extend_map<I, T>(
    out: &mut Vec<T>,
    items: I,
    min: usize,
    f: impl Fn(I::Item) -> T + Sync + Send,
) where
    I: IndexedParallelIterator,
    T: Send,
{
    if on_this_thread(items.len(), min) {
        items.with_producer(ExtendMap(out, f))
    } else {
        out.par_extend(items.with_min_len(min).map(f))
    }
}

/// Appends to `out` every `f(item)` that is `Some`, in the items' order; on this thread or the
/// pool by the rule of [`for_each`].
pub fn extend_filter_map<I, T>(
    out: &mut Vec<T>,
    items: I,
    min: usize,
    f: impl Fn(I::Item) -> Option<T> + Sync + Send,
) where
    I: IndexedParallelIterator,
    T: Send,
{
    if on_this_thread(items.len(), min) {
        items.with_producer(ExtendFilterMap(out, f))
    } else {
        out.par_extend(items.with_min_len(min).filter_map(f))
    }
}

/// [`extend_filter_map`] into a new vector.
pub fn filter_map<I, T>(
    items: I,
    min: usize,
    f: impl Fn(I::Item) -> Option<T> + Sync + Send,
) -> Vec<T>
where
    I: IndexedParallelIterator,
    T: Send,
{
    let mut out = Vec::new();
    extend_filter_map(&mut out, items, min, f);
    out
}

/// A producer's items passed to `f` on this thread, with no splitting.
struct ForEach<F>(F);

impl<T, F: Fn(T)> ProducerCallback<T> for ForEach<F> {
    type Output = ();
    fn callback<P: Producer<Item = T>>(self, producer: P) {
        producer.into_iter().for_each(self.0)
    }
}

/// A producer's items mapped by `f` onto the vector, on this thread (an exact length, so the
/// vector grows once).
struct ExtendMap<'a, U, F>(&'a mut Vec<U>, F);

impl<T, U, F: Fn(T) -> U> ProducerCallback<T> for ExtendMap<'_, U, F> {
    type Output = ();
    fn callback<P: Producer<Item = T>>(self, producer: P) {
        self.0.extend(producer.into_iter().map(self.1))
    }
}

/// A producer's items filtered and mapped by `f` onto the vector, on this thread.
struct ExtendFilterMap<'a, U, F>(&'a mut Vec<U>, F);

impl<T, U, F: Fn(T) -> Option<U>> ProducerCallback<T> for ExtendFilterMap<'_, U, F> {
    type Output = ();
    fn callback<P: Producer<Item = T>>(self, producer: P) {
        self.0.extend(producer.into_iter().filter_map(self.1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On both sides of the threshold (and on a pool of three threads, where the long passes
    /// split), every item is visited once and the lists come out in the items' order.
    #[test]
    fn passes_match_the_serial_ones_on_both_sides_of_the_threshold() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(3)
            .build()
            .unwrap();
        let min = 8;
        for n in [0, 1, 7, 2 * min - 1, 2 * min, 5 * min + 3, 1000] {
            pool.install(|| {
                let mut visited = vec![0u32; n];
                for_each(visited.par_iter_mut(), min, |v| *v += 1);
                assert!(visited.iter().all(|&v| v == 1), "n = {n}");

                let values: Vec<u64> = (0..n as u64).map(|i| i * 7919 % 1013).collect();
                let mut squares = vec![u64::MAX];
                extend_map(&mut squares, values.par_iter(), min, |v| v * v);
                let expected: Vec<u64> = std::iter::once(u64::MAX)
                    .chain(values.iter().map(|v| v * v))
                    .collect();
                assert_eq!(squares, expected, "n = {n}");

                let odd = |(i, v): (usize, &u64)| (v % 2 == 1).then_some((i, *v));
                let kept = filter_map(values.par_iter().enumerate(), min, odd);
                let expected: Vec<(usize, u64)> =
                    values.iter().enumerate().filter_map(odd).collect();
                assert_eq!(kept, expected, "n = {n}");
            });
        }
    }
}
