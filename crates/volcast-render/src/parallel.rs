//! Parallel loops behind a dynamic closure. rayon's machinery (its producers,
//! consumers and jobs) is compiled once per closure type, and a closure written
//! inside a function generic over the voxel type, the filter or the render mode is
//! a new type for each of them; going through `&dyn Fn` compiles the machinery once
//! per result type instead, for one dynamic call per index, run or chunk. This keeps
//! the release build within its time budget.

use std::ops::Range;

use rayon::prelude::*;

/// `[f(0), f(1), ..., f(count - 1)]`, computed in parallel, in index order.
pub(crate) fn map_indices<R: Send>(count: usize, f: &(dyn Fn(usize) -> R + Sync)) -> Vec<R> {
    (0..count).into_par_iter().map(f).collect()
}

/// `f` of each of a few consecutive runs of `0..count` per thread, computed in
/// parallel, in order: for loops that accumulate into a large buffer per run (a
/// histogram) rather than one per index.
pub(crate) fn map_runs<R: Send>(count: usize, f: &(dyn Fn(Range<usize>) -> R + Sync)) -> Vec<R> {
    let run = count.div_ceil(4 * rayon::current_num_threads()).max(1);
    map_indices(count.div_ceil(run), &|r| {
        f(r * run..((r + 1) * run).min(count))
    })
}

/// `f(k, chunk)` of each chunk of `chunk_len` values of `data` (chunk `k` starts at
/// `k * chunk_len`; the last one may be shorter), computed in parallel, in order.
pub(crate) fn map_chunks_mut<T: Send, R: Send>(
    data: &mut [T],
    chunk_len: usize,
    f: &(dyn Fn(usize, &mut [T]) -> R + Sync),
) -> Vec<R> {
    data.par_chunks_mut(chunk_len.max(1))
        .enumerate()
        .map(|(k, chunk)| f(k, chunk))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn indices_map_in_order_and_runs_and_chunks_cover_the_data() {
        assert_eq!(map_indices(5, &|i| i * i), vec![0, 1, 4, 9, 16]);
        assert!(map_indices(0, &|i| i).is_empty());
        for count in [0, 1, 7, 100, 1001] {
            let runs = map_runs(count, &|r| r);
            let all: Vec<usize> = runs.into_iter().flatten().collect();
            assert_eq!(all, (0..count).collect::<Vec<_>>());
        }
        let mut v = vec![0usize; 10];
        let lens = map_chunks_mut(&mut v, 4, &|k, c| {
            for (i, x) in c.iter_mut().enumerate() {
                *x = 4 * k + i;
            }
            c.len()
        });
        assert_eq!(v, (0..10).collect::<Vec<_>>());
        assert_eq!(lens, vec![4, 4, 2]);
    }
}
