//! Kernel benchmarks (`cargo bench`): the reconstruction filters and the
//! integrators on rays through the common benchmark's field (four Gaussian blobs and
//! a thin shell, `bench::blobs`), 8-bit, with and without empty-space skipping.
//! Whole frames are measured by `volcast bench speed`.

use divan::{black_box, Bencher};
use glam::{DMat3, DVec3};
use volcast::mode::projection::Mip;
use volcast::mode::xray::Xray;
use volcast::render::integrator::{trace, Integrand, PixelRay};
use volcast::render::march::March;
use volcast::render::skip::{MacroGrid, Support};
use volcast::render::IndexFrame;
use volcast::sample::{
    bits_table, pair_table, CellCache, Field, GradientMethod, Gradients, Grid, Normalize, Trilinear,
};
use volcast::scene::XrayOutput;
use volcast::volume::{Geometry, ScalarType, Voxels};

fn main() {
    divan::main();
}

const N: usize = 128;

/// The common benchmark's field on an `N`^3 grid, as uint8.
fn volume() -> Vec<u8> {
    let blobs = [
        (-0.30, -0.20, 0.10, 0.18, 1.00),
        (0.35, 0.10, -0.20, 0.12, 0.80),
        (0.05, 0.40, 0.35, 0.10, 0.60),
        (0.00, -0.35, -0.35, 0.22, 0.45),
    ];
    let c = |i: usize| (i as f64 + 0.5) / N as f64 * 2.0 - 1.0;
    let mut v = Vec::with_capacity(N * N * N);
    for k in 0..N {
        for j in 0..N {
            for i in 0..N {
                let (x, y, z) = (c(i), c(j), c(k));
                let mut f: f64 = blobs
                    .iter()
                    .map(|&(cx, cy, cz, s, a)| {
                        let d2 = (x - cx).powi(2) + (y - cy).powi(2) + (z - cz).powi(2);
                        a * (-d2 / (2.0 * s * s)).exp()
                    })
                    .sum();
                let r = (x * x + y * y + z * z).sqrt();
                f += 0.35 * (-(r - 0.8).powi(2) / (2.0 * 0.015f64.powi(2))).exp();
                if f < 1e-3 {
                    f = 0.0;
                }
                v.push((255.0 * f.clamp(0.0, 1.0)).round() as u8);
            }
        }
    }
    v
}

struct Setup {
    data: Vec<u8>,
    lut: Vec<f32>,
    /// The table of normalised pairs the renderer's trilinear passes over 8-bit data
    /// read (`Grid::with_pairs`).
    pairs: Vec<[f32; 2]>,
    frame: IndexFrame,
}

impl Setup {
    fn new() -> Setup {
        let norm = Normalize::new(0.0, 255.0);
        let lut = bits_table(ScalarType::Uint8, norm).unwrap();
        Setup {
            data: volume(),
            pairs: pair_table(&lut),
            lut,
            frame: IndexFrame::new([N; 3], None, &Geometry::default(), DMat3::IDENTITY),
        }
    }

    fn field(&self) -> Trilinear<'_, u8> {
        Trilinear {
            grid: Grid::new(
                Voxels::from_slice(&self.data),
                [N; 3],
                Normalize::new(0.0, 255.0),
                &self.lut,
            )
            .with_pairs(&self.pairs),
            gradients: Gradients::new(GradientMethod::Central, None, DMat3::IDENTITY),
        }
    }

    /// Orthographic rays along +y through a `side` x `side` grid of pixels.
    fn rays(&self, side: usize) -> Vec<PixelRay> {
        let mut rays = Vec::new();
        for j in 0..side {
            for i in 0..side {
                let o = DVec3::new(
                    (i as f64 + 0.5) / side as f64 * N as f64 - 0.5,
                    -10.0,
                    (j as f64 + 0.5) / side as f64 * N as f64 - 0.5,
                );
                let index = self.frame.to_index(o, DVec3::Y);
                if let Some((t_enter, t_exit)) = self.frame.clip(&index, 0.0) {
                    rays.push(PixelRay {
                        origin: o,
                        dir: DVec3::Y,
                        index,
                        t_enter,
                        t_exit,
                        t_depth_ref: t_enter,
                        cut: None,
                        walk: [t_enter, t_exit],
                    });
                }
            }
        }
        rays
    }
}

/// One trilinear sample of 8-bit voxels, at positions along a ray.
#[divan::bench]
fn trilinear_sample_u8(b: Bencher) {
    let s = Setup::new();
    let f = s.field();
    let ray = s.rays(7)[24];
    let m = March::new(ray.t_enter, ray.t_exit, 0.5);
    b.counter(divan::counter::ItemsCount::new(m.len()))
        .bench(|| {
            let mut acc = 0.0f32;
            for i in 0..m.len() {
                acc += f.value(black_box(ray.index.at(m.t(i))));
            }
            acc
        });
}

/// Trilinear samples of 8-bit voxels along one ray, handed over in calls of `run`
/// samples (`Field::values_along`, the vector path where the machine has one): the
/// cost of a call against its samples, as the renderers' runs (a macrocell's span,
/// a batch of 64) make them. Items: samples.
#[divan::bench(args = [8, 16, 64])]
fn values_along_u8(b: Bencher, run: usize) {
    let s = Setup::new();
    let f = s.field();
    let ray = s.rays(7)[24];
    let m = March::new(ray.t_enter, ray.t_exit, 0.5);
    let ts: Vec<f64> = (0..m.len()).map(|i| m.t(i)).collect();
    let mut out = vec![0.0f32; ts.len()];
    let mut cache = CellCache::default();
    b.counter(divan::counter::ItemsCount::new(ts.len()))
        .bench_local(|| {
            for (t, o) in ts.chunks(run).zip(out.chunks_mut(run)) {
                f.values_along(ray.index.o, ray.index.d, black_box(t), o, &mut cache);
            }
            black_box(&out);
        });
}

/// `support`: the grid kind the renderer gives the mode (`RenderPass::new`).
fn integrate(b: Bencher, integrand: impl Integrand, support: Support, skip: bool) {
    let s = Setup::new();
    let f = s.field();
    let rays = s.rays(64);
    let grid = MacroGrid::build([N; 3], support, |r, w, o| f.grid.row_ranges(r, w, o));
    let nominal: usize = rays
        .iter()
        .map(|r| March::new(r.t_enter, r.t_exit, 0.5).len())
        .sum();
    b.counter(divan::counter::ItemsCount::new(nominal))
        .bench(|| {
            let mut acc = 0.0f32;
            for r in &rays {
                let m = March::new(r.t_enter, r.t_exit, 0.5);
                acc += integrand.trace(&f, r, &m, skip.then_some(&grid)).0[0];
            }
            acc
        });
}

/// MIP of 64 x 64 rays at a 0.5-voxel step (items: nominal samples).
#[divan::bench(args = [false, true])]
fn mip_rays(b: Bencher, skip: bool) {
    integrate(b, Mip, Support::LinearTight, skip);
}

/// X-ray of 64 x 64 rays at a 0.5-voxel step (items: nominal samples).
#[divan::bench(args = [false, true])]
fn xray_rays(b: Bencher, skip: bool) {
    integrate(
        b,
        Xray {
            output: XrayOutput::Integral,
            mu: 1.0,
        },
        Support::Linear,
        skip,
    );
}

#[allow(dead_code)]
fn unused() -> ([f32; 4], u64) {
    let s = Setup::new();
    let r = s.rays(1)[0];
    trace(&Mip, &s.field(), &r, 0.5, 0.0)
}
