//! Loops over elements that run in parallel only when there is enough work to share.
//!
//! A rayon call made from outside its pool hands the work to a pool thread and sleeps on a
//! latch until it is done: a few tens of microseconds of thread wake-ups per call, whatever
//! the work. A step of a 216-tet scene makes dozens of such calls for ~100 µs of arithmetic
//! each; below [`MIN_PARALLEL_ITEMS`] the loops run on the calling thread instead.

use rayon::prelude::*;

/// Fewest items a loop needs before it runs in parallel: two tasks of
/// [`MIN_TASK_ITEMS`].
pub const MIN_PARALLEL_ITEMS: usize = 2 * MIN_TASK_ITEMS;

/// Fewest items a parallel task takes: below this the scheduling costs more than it saves
/// (an element kernel takes ~1 µs).
pub const MIN_TASK_ITEMS: usize = 256;

/// `(0..n).map(f).collect()`, in parallel when `n` is large enough; the result is the same
/// either way.
pub fn map_range<T, F>(n: usize, f: F) -> Vec<T>
where
    T: Send,
    F: Fn(usize) -> T + Sync + Send,
{
    if n < MIN_PARALLEL_ITEMS {
        (0..n).map(f).collect()
    } else {
        (0..n)
            .into_par_iter()
            .with_min_len(MIN_TASK_ITEMS)
            .map(f)
            .collect()
    }
}

/// Runs `f(scratch, item)` on every item of `items`, in parallel when there are enough; each
/// task starts with its own `scratch` from `init`.
pub fn for_each_with_scratch<I, S, Init, F>(items: &[I], init: Init, f: F)
where
    I: Sync,
    Init: Fn() -> S + Sync + Send,
    F: Fn(&mut S, &I) + Sync + Send,
{
    if items.len() < MIN_PARALLEL_ITEMS {
        let mut scratch = init();
        items.iter().for_each(|item| f(&mut scratch, item));
    } else {
        items
            .par_iter()
            .with_min_len(MIN_TASK_ITEMS)
            .for_each_init(init, f);
    }
}

/// Runs `f(index, item)` on every item of `items` in place, in parallel when there are enough.
pub fn for_each_mut<T, F>(items: &mut [T], f: F)
where
    T: Send,
    F: Fn(usize, &mut T) + Sync + Send,
{
    if items.len() < MIN_PARALLEL_ITEMS {
        items
            .iter_mut()
            .enumerate()
            .for_each(|(i, item)| f(i, item));
    } else {
        items
            .par_iter_mut()
            .with_min_len(MIN_TASK_ITEMS)
            .enumerate()
            .for_each(|(i, item)| f(i, item));
    }
}
