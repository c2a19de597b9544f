//! The step's large buffers are cleared and refilled every step. Grown by doubling, a buffer
//! can hold twice what the busiest step needs, and a grown copy exists beside the old one while
//! it moves; at 100,000 bodies in contact that is most of a scene's peak memory. These helpers
//! keep a buffer near the size of its busiest step.

use super::parallel;
use rayon::prelude::*;
use std::ops::Range;

/// Clears `v` and makes room for `n` items, with a thirty-second of slack when it has too
/// little. The buffer is grown in place (`realloc` of an empty vector): the allocator moves a
/// large block's pages (`mremap`) instead of copying them, and the pages already touched stay
/// mapped, so only the added room is faulted in. Freeing it and taking a new one faulted in the
/// whole buffer again at every growth, which an eighth of slack kept rare but which then came
/// on top of the busiest step's needs.
pub fn clear_for<T>(v: &mut Vec<T>, n: usize) {
    v.clear();
    if v.capacity() < n {
        v.reserve_exact(n + n / 32);
    }
}

/// Room for `n` more items in `v`, taken exactly (not by doubling) when it has too little.
pub fn reserve_exact<T>(v: &mut Vec<T>, n: usize) {
    if v.capacity() - v.len() < n {
        v.reserve_exact(n);
    }
}

/// `0..n` in consecutive ranges of `block`. rayon collects an unindexed parallel iterator (a
/// `filter_map`) into per-thread vectors before it copies them into the destination: extended
/// a block at a time, that second copy is one block, not everything added.
pub fn blocks(n: usize, block: usize) -> impl Iterator<Item = Range<usize>> {
    let block = block.max(1);
    (0..n)
        .step_by(block)
        .map(move |start| start..(start + block).min(n))
}

/// `items` cut into consecutive runs of the given lengths (which must not add up to more than
/// it holds), so that runs can be filled in parallel.
pub fn runs<T>(mut items: &mut [T], lengths: impl Iterator<Item = usize>) -> Vec<&mut [T]> {
    lengths
        .map(|n| {
            let (run, rest) = std::mem::take(&mut items).split_at_mut(n);
            items = rest;
            run
        })
        .collect()
}

/// Fewest items a list's pass shares among threads (see [`parallel`]): rayon's machinery costs
/// more than a few bodies' work (listing a chain's 18 bodies through it made two-chain's step
/// 4 % slower).
const PARALLEL_ITEMS: usize = 4096;

/// Replaces `out` with the indices `i < n` for which `keep(i)`, ascending; on all threads
/// when `n` is large.
pub fn indices_where(n: usize, keep: impl Fn(usize) -> bool + Sync + Send, out: &mut Vec<usize>) {
    out.clear();
    let all = (0..n).into_par_iter();
    parallel::extend_filter_map(out, all, PARALLEL_ITEMS, |i| keep(i).then_some(i));
}

/// Replaces `out` with `f(i)` for `i < n`, in order; on all threads when `n` is large.
pub fn map_indices<T: Send>(n: usize, f: impl Fn(usize) -> T + Sync + Send, out: &mut Vec<T>) {
    out.clear();
    parallel::extend_map(out, (0..n).into_par_iter(), PARALLEL_ITEMS, f);
}

/// Asks the cache for the lines of the item at `item`: a hint, nothing is read or written, so
/// any address will do (nothing happens off x86-64). Where a loop's next reads are known but
/// scattered over more memory than the caches hold, asking a few items ahead hides the wait.
#[inline(always)]
pub fn prefetch<T>(item: *const T) {
    prefetch_bytes(item.cast(), std::mem::size_of::<T>());
}

/// [`prefetch`] for the `bytes` bytes at `start` only: each 64-byte line they touch, once.
#[inline(always)]
pub fn prefetch_bytes(start: *const u8, bytes: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        // From the start of `start`'s line: an item that straddles a line boundary touches one
        // line more than its size in lines.
        let skew = start.addr() % 64;
        let first = start.wrapping_sub(skew).cast::<i8>();
        for offset in (0..skew + bytes).step_by(64) {
            // SAFETY: PREFETCHh has no architectural effect and raises no exception, whatever
            // the address; x86-64 always has it (SSE).
            unsafe { _mm_prefetch::<_MM_HINT_T0>(first.wrapping_add(offset)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (start, bytes);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both sides of the threshold give what the serial filter and map give, in order.
    #[test]
    fn index_lists_match_the_serial_ones_on_both_sides_of_the_threshold() {
        for n in [
            0,
            1,
            100,
            PARALLEL_ITEMS - 1,
            PARALLEL_ITEMS,
            3 * PARALLEL_ITEMS + 17,
        ] {
            let keep = |i: usize| i % 7 == 3 || i.is_multiple_of(11);
            let mut out = vec![usize::MAX];
            indices_where(n, keep, &mut out);
            assert_eq!(out, (0..n).filter(|&i| keep(i)).collect::<Vec<_>>(), "{n}");
            let mut flags = vec![true; 5];
            map_indices(n, keep, &mut flags);
            assert_eq!(flags, (0..n).map(keep).collect::<Vec<_>>(), "{n}");
        }
    }

    #[test]
    fn blocks_keep_the_order_and_skip_nothing() {
        let mut out = vec![-1];
        for r in blocks(1000, 64) {
            out.par_extend(r.into_par_iter().filter(|i| i % 3 != 0).map(|i| i as i64));
        }
        let expected: Vec<i64> = std::iter::once(-1)
            .chain((0..1000).filter(|i| i % 3 != 0))
            .collect();
        assert_eq!(out, expected);
        assert_eq!(blocks(0, 64).count(), 0);
        assert_eq!(blocks(128, 64).count(), 2);
    }

    #[test]
    fn runs_cover_the_slice_in_order() {
        let mut items: Vec<usize> = (0..10).collect();
        let runs = runs(&mut items, [3, 0, 4, 3].into_iter());
        let lengths: Vec<usize> = runs.iter().map(|r| r.len()).collect();
        assert_eq!(lengths, [3, 0, 4, 3]);
        assert_eq!(runs[2], [3, 4, 5, 6]);
    }

    #[test]
    fn a_short_buffer_is_replaced_not_grown() {
        let mut v: Vec<u64> = Vec::with_capacity(10);
        v.extend(0..10);
        clear_for(&mut v, 80);
        assert!(v.is_empty() && (80..=90).contains(&v.capacity()));
        clear_for(&mut v, 40);
        assert!(v.capacity() >= 80, "a big enough buffer is kept");
    }
}
