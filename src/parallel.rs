//! Parallel loops behind a dynamic closure. rayon's machinery (its producers,
//! consumers and jobs) is compiled once per closure type, and a closure written
//! inside a function generic over the voxel type, the filter or the render mode is
//! a new type for each of them; going through `&dyn Fn` compiles the machinery once
//! per result type instead, for one dynamic call per index or chunk. This keeps the
//! release build within its time budget.

use rayon::prelude::*;

/// `[f(0), f(1), ..., f(count - 1)]`, computed in parallel, in index order.
pub(crate) fn map_indices<R: Send>(count: usize, f: &(dyn Fn(usize) -> R + Sync)) -> Vec<R> {
    (0..count).into_par_iter().map(f).collect()
}

/// Calls `f(k, chunk)` in parallel for the chunks of `chunk_len` values of `data`
/// (chunk `k` starts at `k * chunk_len`; the last one may be shorter).
pub(crate) fn for_each_chunk_mut<T: Send>(
    data: &mut [T],
    chunk_len: usize,
    f: &(dyn Fn(usize, &mut [T]) + Sync),
) {
    data.par_chunks_mut(chunk_len.max(1))
        .enumerate()
        .for_each(|(k, chunk)| f(k, chunk));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn indices_map_in_order_and_chunks_cover_the_data() {
        assert_eq!(map_indices(5, &|i| i * i), vec![0, 1, 4, 9, 16]);
        assert!(map_indices(0, &|i| i).is_empty());
        let mut v = vec![0usize; 10];
        for_each_chunk_mut(&mut v, 4, &|k, c| {
            for (i, x) in c.iter_mut().enumerate() {
                *x = 4 * k + i;
            }
        });
        assert_eq!(v, (0..10).collect::<Vec<_>>());
    }
}
