//! Per-object work that needs no other object's result, spread over Bevy's
//! [`ComputeTaskPool`] (issue #44): the LOD stages are otherwise serial, and while one
//! of them runs the other cores wait for it.

use bevy::tasks::{ComputeTaskPool, ParallelSliceMut, TaskPool};

/// Objects per task: large enough that spawning a task (a few microseconds) is a small
/// part of its work (a floor is ~0.1 µs), small enough to share a 40 000-object frame
/// among eight threads.
const CHUNK: usize = 2048;

/// Fills `out[i]` with `each(i)` for every `i`, in chunks spread over the compute task
/// pool when there is one with more than one thread and more than one chunk of work;
/// serially otherwise. The result is the same either way: each slot is written once, by
/// the same function of its index.
pub(super) fn fill_each<T: Send>(out: &mut [T], each: impl Fn(usize) -> T + Sync) {
    fill_each_on(ComputeTaskPool::try_get().map(|pool| &**pool), out, each);
}

/// [`fill_each`] on `pool`.
fn fill_each_on<T: Send>(pool: Option<&TaskPool>, out: &mut [T], each: impl Fn(usize) -> T + Sync) {
    // Chunk `c` of `CHUNK` slots; serially the whole slice is chunk 0.
    let fill = |c: usize, chunk: &mut [T]| {
        for (j, slot) in chunk.iter_mut().enumerate() {
            *slot = each(c * CHUNK + j);
        }
    };
    match pool.filter(|pool| pool.thread_num() > 1 && out.len() > CHUNK) {
        Some(pool) => {
            // (The reference is the slice type the trait is implemented for.)
            let mut out = out;
            out.par_chunk_map_mut(pool, CHUNK, fill);
        }
        None => fill(0, out),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy::tasks::TaskPoolBuilder;

    /// Every slot holds its own index's result, whether the work was split or not: a
    /// chunk written at another chunk's indices, or a chunk left out, fails it.
    #[test]
    fn every_slot_gets_its_own_result_split_or_not() {
        let each = |i: usize| (i as u64) * 7 + 3;
        let expected: Vec<u64> = (0..10 * CHUNK + 17).map(each).collect();
        let four = TaskPoolBuilder::new().num_threads(4).build();
        for pool in [None, Some(&four)] {
            for len in [0, 1, CHUNK, CHUNK + 1, 10 * CHUNK + 17] {
                let mut out = vec![0; len];
                fill_each_on(pool, &mut out, each);
                assert_eq!(out, expected[..len], "{len} slots, pool {}", pool.is_some());
            }
        }
    }
}
