//! Whole-volume precomputations a pass may need: prefiltered cubic B-spline
//! coefficients and a gradient volume. Only passes that use them build them.

use crate::parallel::{map_chunks_mut, map_indices};

use super::{GradientMethod, Normalize};
use crate::volume::{Voxel, Voxels};

/// The pole of the cubic B-spline prefilter, `sqrt(3) - 2` (Unser 1999).
const POLE: f64 = -0.267_949_192_431_122_7;

/// Coefficients `c` such that the cubic B-spline through `c` interpolates the
/// normalised voxel values (mirror boundary conditions), as `f32`.
pub fn prefilter_cubic<'a, T: Voxel>(
    data: impl Into<Voxels<'a, T>>,
    n: [usize; 3],
    norm: Normalize,
) -> Vec<f32> {
    let data = data.into();
    prefilter_normalised(n, |i| norm.apply(data.get(i).to_f64()))
}

/// [`prefilter_cubic`] of the voxels whose normalised values are `value(flat index)`.
pub fn prefilter_normalised(n: [usize; 3], value: impl Fn(usize) -> f32 + Sync) -> Vec<f32> {
    let mut c = vec![0.0f64; n[0] * n[1] * n[2]];
    let slab = n[0] * n[1];
    map_chunks_mut(&mut c, slab, &|k, out| {
        for (i, v) in out.iter_mut().enumerate() {
            *v = f64::from(value(k * slab + i));
        }
    });
    prefilter_volume(c, n)
}

/// The prefilter along x, y and z of the values `c` of an `n` grid, as `f32`.
fn prefilter_volume(mut c: Vec<f64>, [nx, ny, nz]: [usize; 3]) -> Vec<f32> {
    // x lines are contiguous
    map_chunks_mut(&mut c, nx, &|_, line| prefilter_line(line));
    // y lines: one z slab at a time
    map_chunks_mut(&mut c, nx * ny, &|_, slab| {
        let mut line = vec![0.0; ny];
        for i in 0..nx {
            for (j, l) in line.iter_mut().enumerate() {
                *l = slab[i + nx * j];
            }
            prefilter_line(&mut line);
            for (j, l) in line.iter().enumerate() {
                slab[i + nx * j] = *l;
            }
        }
    });
    // z lines: gather columns in parallel, then scatter back
    let sxy = nx * ny;
    let cols: Vec<Vec<f64>> = map_indices(sxy, &|ij| {
        let mut line: Vec<f64> = (0..nz).map(|k| c[ij + sxy * k]).collect();
        prefilter_line(&mut line);
        line
    });
    for (ij, col) in cols.iter().enumerate() {
        for (k, v) in col.iter().enumerate() {
            c[ij + sxy * k] = *v;
        }
    }
    c.into_iter().map(|v| v as f32).collect()
}

/// In-place cubic B-spline prefilter of one line (causal + anti-causal recursion
/// with exact mirror-boundary initialisation).
fn prefilter_line(c: &mut [f64]) {
    let n = c.len();
    if n < 2 {
        return;
    }
    let z = POLE;
    let gain = (1.0 - z) * (1.0 - 1.0 / z);
    c.iter_mut().for_each(|v| *v *= gain);
    // causal initialisation: sum over the mirrored signal
    let z_n1 = z.powi(n as i32 - 1);
    let mut sum = c[0] + z_n1 * c[n - 1];
    let mut zk = z;
    let mut z2k = z_n1 * z_n1 / z;
    for v in c.iter().take(n - 1).skip(1) {
        sum += (zk + z2k) * v;
        zk *= z;
        z2k /= z;
    }
    c[0] = sum / (1.0 - z_n1 * z_n1);
    for k in 1..n {
        c[k] += z * c[k - 1];
    }
    c[n - 1] = (z / (z * z - 1.0)) * (c[n - 1] + z * c[n - 2]);
    for k in (0..n - 1).rev() {
        c[k] = z * (c[k + 1] - c[k]);
    }
}

/// Index-space gradient of the normalised voxels at every voxel.
pub fn gradient_volume<'a, T: Voxel>(
    data: impl Into<Voxels<'a, T>>,
    n: [usize; 3],
    norm: Normalize,
    method: GradientMethod,
) -> Vec<[f32; 3]> {
    let data = data.into();
    gradient_volume_normalised(n, method, |i| norm.apply(data.get(i).to_f64()))
}

/// [`gradient_volume`] of the voxels whose normalised values are `value(flat index)`.
pub fn gradient_volume_normalised(
    n: [usize; 3],
    method: GradientMethod,
    value: impl Fn(usize) -> f32 + Sync,
) -> Vec<[f32; 3]> {
    let [nx, ny, nz] = n;
    let get = |i: isize, j: isize, k: isize| {
        let c = |x: isize, m: usize| x.clamp(0, m as isize - 1) as usize;
        value(c(i, nx) + nx * (c(j, ny) + ny * c(k, nz)))
    };
    let mut out = vec![[0.0f32; 3]; nx * ny * nz];
    let slab = nx * ny;
    let inner = |x: usize, m: usize| x >= 1 && x + 1 < m;
    map_chunks_mut(&mut out, slab, &|k, g| {
        for (j, row) in g.chunks_mut(nx.max(1)).enumerate() {
            let central_row = method == GradientMethod::Central && inner(j, ny) && inner(k, nz);
            for (i, g) in row.iter_mut().enumerate() {
                *g = if central_row && inner(i, nx) {
                    // `grid_gradient`'s central difference where its clamps change
                    // nothing: the same operations on the same values
                    let at = i + nx * (j + ny * k);
                    let d = |s: usize| (value(at + s) - value(at - s)) / 2.0;
                    [d(1), d(nx), d(slab)]
                } else {
                    grid_gradient(method, n, [i, j, k], get)
                };
            }
        }
    });
    out
}

/// The gradient estimator at one voxel; `get` reads normalised voxels with clamped
/// indices. Along each axis the difference spans two voxels inside the grid and one
/// at its border (one-sided), and is zero on an axis of a single voxel.
pub(super) fn grid_gradient(
    method: GradientMethod,
    n: [usize; 3],
    [i, j, k]: [usize; 3],
    get: impl Fn(isize, isize, isize) -> f32,
) -> [f32; 3] {
    let p = [i as isize, j as isize, k as isize];
    let mut g = [0.0f32; 3];
    for (axis, ga) in g.iter_mut().enumerate() {
        let lo = (p[axis] - 1).max(0);
        let hi = (p[axis] + 1).min(n[axis] as isize - 1);
        if hi == lo {
            continue;
        }
        let h = (hi - lo) as f32;
        let at = |offset: [isize; 3], a: isize| {
            let mut q = [p[0] + offset[0], p[1] + offset[1], p[2] + offset[2]];
            q[axis] = a;
            get(q[0], q[1], q[2])
        };
        *ga = match method {
            // analytic gradients come from the spline (`Sampler::gradient`); a grid
            // estimate for them is the central difference
            GradientMethod::Central | GradientMethod::Analytic => {
                (at([0; 3], hi) - at([0; 3], lo)) / h
            }
            GradientMethod::Sobel => {
                let (u, v) = match axis {
                    0 => (1, 2),
                    1 => (0, 2),
                    _ => (0, 1),
                };
                let mut sum = 0.0;
                for (du, wu) in [(-1isize, 1.0f32), (0, 2.0), (1, 1.0)] {
                    for (dv, wv) in [(-1isize, 1.0f32), (0, 2.0), (1, 1.0)] {
                        let mut off = [0isize; 3];
                        off[u] = du;
                        off[v] = dv;
                        sum += wu * wv * (at(off, hi) - at(off, lo));
                    }
                }
                sum / (16.0 * h)
            }
        };
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The gradient volume (rows in order; central differences inside the grid
    /// taken directly) holds the bits of `grid_gradient` at every voxel, for each
    /// estimator, in grids with axes of one to five voxels.
    #[test]
    fn gradient_volume_is_grid_gradient_at_every_voxel() {
        for n in [
            [5usize, 4, 3],
            [1, 4, 5],
            [3, 1, 3],
            [2, 2, 2],
            [5, 3, 1],
            [1, 1, 1],
        ] {
            let len = n[0] * n[1] * n[2];
            let v: Vec<f32> = (0..len)
                .map(|i| ((i * 37 % 17) as f32 / 7.0).sin())
                .collect();
            let get = |i: isize, j: isize, k: isize| {
                let c = |x: isize, m: usize| x.clamp(0, m as isize - 1) as usize;
                v[c(i, n[0]) + n[0] * (c(j, n[1]) + n[1] * c(k, n[2]))]
            };
            for method in [GradientMethod::Central, GradientMethod::Sobel] {
                let g = gradient_volume_normalised(n, method, |i| v[i]);
                for k in 0..n[2] {
                    for j in 0..n[1] {
                        for i in 0..n[0] {
                            let want = grid_gradient(method, n, [i, j, k], get);
                            let got = g[i + n[0] * (j + n[1] * k)];
                            assert_eq!(
                                got.map(f32::to_bits),
                                want.map(f32::to_bits),
                                "{method:?} at {:?} of {n:?}",
                                [i, j, k]
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn prefilter_then_bspline_interpolates_a_line() {
        let orig = [0.1, 0.9, 0.3, 0.5, 0.2, 0.8];
        let mut c = orig.to_vec();
        prefilter_line(&mut c);
        // B-spline at integer k: (c[k-1] + 4 c[k] + c[k+1]) / 6 with mirror ends
        let n = c.len();
        for k in 0..n {
            let l = if k == 0 { c[1] } else { c[k - 1] };
            let r = if k == n - 1 { c[n - 2] } else { c[k + 1] };
            let v = (l + 4.0 * c[k] + r) / 6.0;
            assert!((v - orig[k]).abs() < 1e-12, "{k}: {v} vs {}", orig[k]);
        }
    }

    #[test]
    fn gradient_volume_matches_on_the_fly() {
        let n = [4, 3, 3];
        let data: Vec<u8> = (0..36).map(|i| (i * 7 % 23) as u8).collect();
        let norm = Normalize::new(0.0, 255.0);
        for m in [GradientMethod::Central, GradientMethod::Sobel] {
            let g = gradient_volume(&data, n, norm, m);
            let get = |i: isize, j: isize, k: isize| {
                let c = |x: isize, mm: usize| x.clamp(0, mm as isize - 1) as usize;
                norm.apply(data[c(i, 4) + 4 * (c(j, 3) + 3 * c(k, 3))] as f64)
            };
            // voxel (2, 1, 1) of a 4 x 3 x 3 grid is at 2 + 4 * (1 + 3 * 1)
            assert_eq!(g[18], grid_gradient(m, n, [2, 1, 1], get));
        }
    }
}
