//! Histograms for transfer-function design: the value histogram of a volume and its
//! 2D histogram of value x gradient magnitude (Kindlmann and Durkin 1998: boundaries
//! between materials show up as arcs, the basis of 2D transfer functions), counted
//! over the voxels, and drawn as plots ([`plot`]) with a scene's windows, iso values,
//! thresholds and transfer functions over them ([`Overlays`]).
//!
//! The value axis is in data units: the volume's physical values (its rescale
//! applied), those of `[volume] window` and of `units = "data"`. The gradient
//! magnitude is the very quantity a composite pass's 2D transfer function looks up:
//! the renderer's grid gradient (`central` or `sobel`, [`crate::sample::Gradients`])
//! of the voxels normalised by the window (so clamped to it, as the renderer reads
//! them), in world units, times the smallest voxel spacing: normalised value per
//! voxel of the smallest spacing. It is computed voxel by voxel as it is counted (no
//! gradient volume is allocated); the voxels are read twice (the axes' ranges first,
//! then the counts).
//!
//! Counting runs in parallel over z slices; the partial counts are integers, so their
//! sum, and every output, is the same whatever the number of threads. Non-finite
//! voxels are not counted (their number is kept); as neighbours they enter the
//! gradients with the values the renderer gives them (NaN and -inf as the window's
//! low end, +inf as its high end).

mod overlays;
pub mod plot;

pub use overlays::{Curve1D, Marker, Overlays, WidgetBox};

use glam::DVec3;

use crate::parallel::{map_indices, map_runs};
use crate::sample::{normalisation_table, GradientMethod, Gradients, Grid, Normalize};
use crate::scene::Scene;
use crate::transfer::Transfer;
use crate::volume::{Rescale, Volume, VolumeHeader, Voxel, Voxels};
use crate::with_voxels;

/// The most value bins.
pub const MAX_BINS: usize = 4096;
/// The most gradient-magnitude bins.
pub const MAX_GRADIENT_BINS: usize = 1024;

/// What to count and how finely.
#[derive(Clone, Debug, PartialEq)]
pub struct Options {
    /// Bins along the value axis (1 to [`MAX_BINS`]).
    pub bins: usize,
    /// Bins along the gradient-magnitude axis of the 2D histogram (1 to
    /// [`MAX_GRADIENT_BINS`]).
    pub gradient_bins: usize,
    /// The top of the gradient axis (larger magnitudes count in the top bin, as the
    /// renderer clamps them to a transfer function's `gradient_max`); `None` = the
    /// largest magnitude in the data.
    pub gradient_max: Option<f64>,
    /// The gradient estimator (`analytic` counts as `central`, the grid estimate the
    /// renderer uses for it too).
    pub gradient: GradientMethod,
    /// Voxel index ranges (inclusive) to count; `None` = every voxel. Gradients are
    /// taken on the whole grid, as the renderer takes them.
    pub crop: Option<[[usize; 2]; 3]>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            bins: 256,
            gradient_bins: 128,
            gradient_max: None,
            gradient: GradientMethod::Central,
            crop: None,
        }
    }
}

impl Options {
    /// The default options with the crop of `scene` and the gradient estimator of
    /// its first composite pass with a 2D transfer function (`central` when it has
    /// none, or is not shaded).
    pub fn for_scene(scene: &Scene) -> Options {
        let gradient = scene
            .passes
            .iter()
            .find(|p| matches!(p.mode.transfer(), Some((_, Transfer::TwoD(_)))))
            .and_then(|p| p.mode.shading())
            .map_or(GradientMethod::Central, |s| s.gradient);
        Options {
            gradient,
            crop: scene.volume().crop,
            ..Options::default()
        }
    }
}

/// Why histograms cannot be counted.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum HistogramError {
    /// The number of value bins is out of range.
    #[error("{0} value bins: expected a whole number from 1 to {MAX_BINS}")]
    Bins(usize),
    /// The number of gradient bins is out of range.
    #[error("{0} gradient bins: expected a whole number from 1 to {MAX_GRADIENT_BINS}")]
    GradientBins(usize),
    /// The top of the gradient axis is not a positive number.
    #[error("gradient axis top {0}: expected a finite number greater than 0")]
    GradientMax(f64),
    /// No voxel has a finite value.
    #[error("the volume {0} has no finite values to count")]
    NoFiniteValues(String),
    /// The crop is not inside the volume.
    #[error("crop {crop:?} is not inside the volume's {sizes:?} voxels")]
    Crop {
        /// The index ranges.
        crop: [[usize; 2]; 3],
        /// The volume's sizes.
        sizes: [usize; 3],
    },
    /// The values, or the gradient magnitudes, span more than an `f64` can measure.
    #[error("the {what} of {volume} span [{lo:e}, {hi:e}], wider than can be binned (the width overflows)")]
    Span {
        /// "values" or "gradient magnitudes".
        what: &'static str,
        /// The volume.
        volume: String,
        /// The smallest.
        lo: f64,
        /// The largest.
        hi: f64,
    },
    /// The volume's axes do not span 3D space (no gradient can be expressed in
    /// world units).
    #[error("the volume {0} has degenerate axes (spacings or directions without an inverse)")]
    Geometry(String),
}

/// The counts, and the axes they are binned on.
#[derive(Clone, Debug, PartialEq)]
pub struct Histograms {
    /// The value axis `[low, high]` in data units: bin `i` spans `low + i w` to
    /// `low + (i + 1) w` with `w = (high - low) / bins` (the last bin includes
    /// `high`). The finite values' range; for integer data widened by half a step
    /// on each side, so that each integer lies at a bin's centre when there are as
    /// many bins as integers.
    pub value_range: [f64; 2],
    /// Voxels per value bin.
    pub counts: Vec<u64>,
    /// The gradient axis `[0, top]` in normalised value per voxel of the smallest
    /// spacing; the top bin also counts the magnitudes above `top`.
    pub gradient_range: [f64; 2],
    /// Bins along the gradient axis.
    pub gradient_bins: usize,
    /// Voxels per (value bin, gradient bin), value fastest: index `j * bins + i`.
    pub counts_2d: Vec<u64>,
    /// The largest gradient magnitude of a counted voxel.
    pub largest_gradient: f64,
    /// Voxels counted (finite, inside the crop).
    pub counted: u64,
    /// Voxels inside the crop not counted because their value is NaN or infinite.
    pub non_finite: u64,
    /// The window the gradients were taken with: the data values at normalised 0
    /// and 1.
    pub window: [f64; 2],
    /// The gradient estimator used.
    pub gradient: GradientMethod,
}

impl Histograms {
    /// Number of value bins.
    pub fn bins(&self) -> usize {
        self.counts.len()
    }

    /// The value bin of data value `x` (clamped to the axis).
    pub fn value_bin(&self, x: f64) -> usize {
        bin_of(x, self.value_range, self.bins())
    }

    /// The gradient bin of magnitude `g` (clamped to the axis).
    pub fn gradient_bin(&self, g: f64) -> usize {
        bin_of(g, self.gradient_range, self.gradient_bins)
    }

    /// The edges `[low, high]` of value bin `i`.
    pub fn value_edges(&self, i: usize) -> [f64; 2] {
        edges(self.value_range, self.bins(), i)
    }

    /// The edges `[low, high]` of gradient bin `j`.
    pub fn gradient_edges(&self, j: usize) -> [f64; 2] {
        edges(self.gradient_range, self.gradient_bins, j)
    }

    /// Voxels in value bin `i` and gradient bin `j`.
    pub fn count_2d(&self, i: usize, j: usize) -> u64 {
        self.counts_2d[j * self.bins() + i]
    }

    /// The value histogram as CSV: `bin,value_low,value_high,count`, one row per bin.
    pub fn csv(&self) -> String {
        let mut s = String::from("bin,value_low,value_high,count\n");
        for (i, c) in self.counts.iter().enumerate() {
            let [a, b] = self.value_edges(i);
            s.push_str(&format!("{i},{a},{b},{c}\n"));
        }
        s
    }

    /// The 2D histogram as CSV: `value_bin,gradient_bin,value_low,value_high,
    /// gradient_low,gradient_high,count`, one row per non-empty cell (value fastest).
    pub fn csv_2d(&self) -> String {
        let mut s = String::from(
            "value_bin,gradient_bin,value_low,value_high,gradient_low,gradient_high,count\n",
        );
        for j in 0..self.gradient_bins {
            for i in 0..self.bins() {
                let c = self.count_2d(i, j);
                if c > 0 {
                    let ([a, b], [g0, g1]) = (self.value_edges(i), self.gradient_edges(j));
                    s.push_str(&format!("{i},{j},{a},{b},{g0},{g1},{c}\n"));
                }
            }
        }
        s
    }
}

/// The bin of `x` on `n` equal bins over `[lo, hi]`, clamped to the axis (NaN
/// counts as the first bin).
fn bin_of(x: f64, [lo, hi]: [f64; 2], n: usize) -> usize {
    let b = ((x - lo) * (n as f64 / (hi - lo))).floor();
    // `as` maps NaN to 0 and saturates
    (b.max(0.0) as usize).min(n - 1)
}

/// The edges of bin `i` of `n` over `[lo, hi]` (the last one ends at `hi`).
fn edges([lo, hi]: [f64; 2], n: usize, i: usize) -> [f64; 2] {
    let at = |k: usize| {
        if k >= n {
            hi
        } else {
            lo + (hi - lo) * k as f64 / n as f64
        }
    };
    [at(i), at(i + 1)]
}

/// The data value of normalised value `t` under the normalisation `norm` of stored
/// values and the volume's `rescale`.
pub fn data_value(norm: Normalize, rescale: Rescale, t: f64) -> f64 {
    let (lo, scale) = norm.lo_scale();
    rescale.apply(lo + t / scale)
}

/// Counts the value and value x gradient-magnitude histograms of `volume`, its
/// voxels normalised by `norm` (the renderer's window) for the gradients.
pub fn compute(
    volume: &Volume,
    norm: Normalize,
    opts: &Options,
) -> Result<Histograms, HistogramError> {
    if !(1..=MAX_BINS).contains(&opts.bins) {
        return Err(HistogramError::Bins(opts.bins));
    }
    if !(1..=MAX_GRADIENT_BINS).contains(&opts.gradient_bins) {
        return Err(HistogramError::GradientBins(opts.gradient_bins));
    }
    if let Some(g) = opts.gradient_max {
        if !(g.is_finite() && g > 0.0) {
            return Err(HistogramError::GradientMax(g));
        }
    }
    let h = &volume.header;
    let n = h.sizes;
    let all = [
        [0, n[0].saturating_sub(1)],
        [0, n[1].saturating_sub(1)],
        [0, n[2].saturating_sub(1)],
    ];
    let crop = opts.crop.unwrap_or(all);
    if n.contains(&0) || (0..3).any(|a| crop[a][0] > crop[a][1] || crop[a][1] >= n[a]) {
        return Err(HistogramError::Crop { crop, sizes: n });
    }
    with_voxels!(&volume.data, v => count(v, h, norm, opts, crop))
}

/// Partial results of pass 1 (over some slices).
#[derive(Clone, Copy)]
struct Ranges {
    min: f64,
    max: f64,
    largest_gradient: f64,
    counted: u64,
    non_finite: u64,
}

impl Ranges {
    const EMPTY: Ranges = Ranges {
        min: f64::INFINITY,
        max: f64::NEG_INFINITY,
        largest_gradient: 0.0,
        counted: 0,
        non_finite: 0,
    };

    fn merge(self, o: Ranges) -> Ranges {
        Ranges {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
            largest_gradient: self.largest_gradient.max(o.largest_gradient),
            counted: self.counted + o.counted,
            non_finite: self.non_finite + o.non_finite,
        }
    }
}

/// Both passes over voxels of type `T`.
fn count<T: Voxel>(
    voxels: Voxels<'_, T>,
    header: &VolumeHeader,
    norm: Normalize,
    opts: &Options,
    crop: [[usize; 2]; 3],
) -> Result<Histograms, HistogramError> {
    let n = header.sizes;
    let lut = normalisation_table::<T>(norm);
    let grid = Grid::new(voxels, n, norm, &lut);
    let index_from_world = header
        .geometry
        .index_from_world_matrix()
        .filter(|m| m.is_finite())
        .ok_or_else(|| HistogramError::Geometry(header.source.clone()))?;
    let method = match opts.gradient {
        GradientMethod::Analytic => GradientMethod::Central,
        m => m,
    };
    let gradients = Gradients::new(method, None, index_from_world);
    let voxel_length = header
        .geometry
        .spacings()
        .into_iter()
        .fold(f64::INFINITY, f64::min);
    // what a composite pass's 2D transfer function looks up at a voxel
    let magnitude = |i: usize, j: usize, k: usize| {
        let p = DVec3::new(i as f64, j as f64, k as f64);
        gradients.interpolated(&grid, p).length() * voxel_length
    };
    let rescale = header.rescale;
    let (sx, sxy) = (n[0], n[0] * n[1]);
    let [[x0, x1], [y0, y1], [z0, z1]] = crop;
    // calls `f(i, j, k, value)` for each voxel of slice k inside the crop
    let each_in_slice = |k: usize, f: &mut dyn FnMut(usize, usize, f64)| {
        for j in y0..=y1 {
            for i in x0..=x1 {
                f(
                    i,
                    j,
                    rescale.apply(voxels.get(i + sx * j + sxy * k).to_f64()),
                );
            }
        }
    };
    let want_gradient = opts.gradient_max.is_none();
    let slices = map_indices((z1 + 1).saturating_sub(z0), &|dk| {
        let k = z0 + dk;
        let mut r = Ranges::EMPTY;
        each_in_slice(k, &mut |i, j, x| {
            if x.is_finite() {
                r.min = r.min.min(x);
                r.max = r.max.max(x);
                r.counted += 1;
                if want_gradient {
                    r.largest_gradient = r.largest_gradient.max(magnitude(i, j, k));
                }
            } else {
                r.non_finite += 1;
            }
        });
        r
    });
    let ranges = slices.into_iter().fold(Ranges::EMPTY, Ranges::merge);
    if ranges.counted == 0 {
        return Err(HistogramError::NoFiniteValues(header.source.clone()));
    }
    let half = if T::TYPE.is_float() {
        0.0
    } else {
        0.5 * rescale.slope.abs()
    };
    let (mut lo, mut hi) = (ranges.min - half, ranges.max + half);
    if lo >= hi {
        (lo, hi) = (ranges.min - 0.5, ranges.max + 0.5);
    }
    let value_range = [lo, hi];
    if !(hi - lo).is_finite() {
        return Err(HistogramError::Span {
            what: "values",
            volume: header.source.clone(),
            lo: ranges.min,
            hi: ranges.max,
        });
    }
    let top = match opts.gradient_max {
        Some(g) => g,
        None if ranges.largest_gradient > 0.0 => ranges.largest_gradient,
        None => 1.0,
    };
    if !top.is_finite() {
        return Err(HistogramError::Span {
            what: "gradient magnitudes",
            volume: header.source.clone(),
            lo: 0.0,
            hi: top,
        });
    }
    let gradient_range = [0.0, top];
    let (bins, gbins) = (opts.bins, opts.gradient_bins);
    // a few runs of slices per thread, each counted into its own histograms
    let parts = map_runs((z1 + 1).saturating_sub(z0), &|run| {
        let (mut c1, mut c2, mut largest) = (vec![0u64; bins], vec![0u64; bins * gbins], 0.0f64);
        for k in z0 + run.start..z0 + run.end {
            each_in_slice(k, &mut |i, j, x| {
                if x.is_finite() {
                    let g = magnitude(i, j, k);
                    largest = largest.max(g);
                    let (vb, gb) = (
                        bin_of(x, value_range, bins),
                        bin_of(g, gradient_range, gbins),
                    );
                    c1[vb] += 1;
                    c2[gb * bins + vb] += 1;
                }
            });
        }
        (c1, c2, largest)
    });
    let (mut counts, mut counts_2d, mut largest) =
        (vec![0u64; bins], vec![0u64; bins * gbins], 0.0f64);
    for (c1, c2, l) in parts {
        counts.iter_mut().zip(c1).for_each(|(a, b)| *a += b);
        counts_2d.iter_mut().zip(c2).for_each(|(a, b)| *a += b);
        largest = largest.max(l);
    }
    Ok(Histograms {
        value_range,
        counts,
        gradient_range,
        gradient_bins: gbins,
        counts_2d,
        largest_gradient: largest,
        counted: ranges.counted,
        non_finite: ranges.non_finite,
        window: [0.0, 1.0].map(|t| data_value(norm, rescale, t)),
        gradient: method,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sample::{Field, Interpolation, Sampler};
    use crate::volume::{Geometry, ScalarType, VolumeData};

    fn volume(ty: ScalarType, sizes: [usize; 3], spacing: [f64; 3], values: &[f64]) -> Volume {
        Volume {
            header: VolumeHeader {
                sizes,
                scalar_type: ty,
                geometry: Geometry::from_spacing(spacing),
                source: "test".into(),
                fields: Vec::new(),
                rescale: Rescale::IDENTITY,
            },
            data: VolumeData::from_f64s(ty, values),
        }
    }

    fn vol_ok() -> Volume {
        volume(
            ScalarType::Uint8,
            [2, 2, 2],
            [1.0; 3],
            &[0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0],
        )
    }

    /// A field with some structure in every direction.
    fn bumpy(n: [usize; 3]) -> Vec<f64> {
        let mut v = Vec::new();
        for k in 0..n[2] {
            for j in 0..n[1] {
                for i in 0..n[0] {
                    let (x, y, z) = (i as f64, j as f64, k as f64);
                    v.push(100.0 + 60.0 * (0.7 * x).sin() * (0.4 * y + 0.3 * z).cos() + 3.0 * z);
                }
            }
        }
        v
    }

    #[test]
    fn gradients_are_what_a_2d_transfer_function_looks_up() {
        // the renderer looks up |field.gradient(p)| * (smallest spacing) at sample p;
        // at a voxel, every filter's grid gradient is the voxel's own
        let n = [9, 7, 6];
        let spacing = [0.8, 1.3, 0.5];
        let vol = volume(ScalarType::Float32, n, spacing, &bumpy(n));
        let norm = Normalize::new(60.0, 150.0); // clamps some voxels, as the renderer does
        let m = vol.header.geometry.index_from_world_matrix().unwrap();
        let values: Vec<f32> = bumpy(n).iter().map(|&v| v as f32).collect();
        for method in [GradientMethod::Central, GradientMethod::Sobel] {
            let opts = Options {
                bins: 16,
                gradient_bins: 1000,
                gradient_max: Some(0.5),
                gradient: method,
                crop: None,
            };
            let h = compute(&vol, norm, &opts).unwrap();
            let field = Sampler::new(
                values.as_slice(),
                n,
                norm,
                Interpolation::Trilinear,
                None,
                method,
                None,
                m,
            );
            let mut expected = vec![0u64; 1000];
            for k in 0..n[2] {
                for j in 0..n[1] {
                    for i in 0..n[0] {
                        let p = DVec3::new(i as f64, j as f64, k as f64);
                        let g = field.gradient(p).length() * 0.5;
                        expected[((g / 0.5 * 1000.0) as usize).min(999)] += 1;
                    }
                }
            }
            let got: Vec<u64> = (0..1000)
                .map(|j| (0..16).map(|i| h.count_2d(i, j)).sum())
                .collect();
            assert_eq!(got, expected, "{method:?}");
            assert_eq!(h.gradient, method);
        }
    }

    #[test]
    fn integer_bins_are_centred_on_integers_and_non_finite_voxels_are_skipped() {
        let n = [3, 2, 2];
        let values = [0.0, 1.0, 1.0, 2.0, 2.0, 2.0, 5.0, 5.0, 5.0, 5.0, 3.0, 4.0];
        let vol = volume(ScalarType::Uint8, n, [1.0; 3], &values);
        let opts = Options {
            bins: 6,
            ..Options::default()
        };
        let h = compute(&vol, Normalize::new(0.0, 5.0), &opts).unwrap();
        assert_eq!(h.value_range, [-0.5, 5.5]);
        assert_eq!(h.counts, vec![1, 2, 3, 1, 1, 4]);
        assert_eq!(h.counted, 12);
        assert_eq!(h.value_edges(5), [4.5, 5.5]);
        // floats: the range itself; NaN and infinities not counted
        let values = [
            0.0,
            f64::NAN,
            1.0,
            f64::INFINITY,
            2.0,
            f64::NEG_INFINITY,
            4.0,
            4.0,
        ];
        let vol = volume(ScalarType::Float32, [2, 2, 2], [1.0; 3], &values);
        let h = compute(&vol, Normalize::new(0.0, 4.0), &opts).unwrap();
        assert_eq!(h.value_range, [0.0, 4.0]);
        assert_eq!((h.counted, h.non_finite), (5, 3));
        // bins of 2/3: 0 -> 0, 1 -> 1, 2 -> 3, 4 -> the last
        assert_eq!(h.counts, vec![1, 1, 0, 1, 0, 2]);
        assert_eq!(h.counts_2d.iter().sum::<u64>(), 5);
    }

    #[test]
    fn a_crop_counts_its_voxels_only() {
        let n = [4, 4, 4];
        let values: Vec<f64> = (0..64).map(|i| f64::from(i % 4)).collect();
        let vol = volume(ScalarType::Uint8, n, [1.0; 3], &values);
        let opts = Options {
            bins: 2,
            crop: Some([[2, 3], [0, 3], [1, 2]]),
            ..Options::default()
        };
        let h = compute(&vol, Normalize::new(0.0, 3.0), &opts).unwrap();
        // x in 2..=3: values 2 and 3, 4 x 2 voxels each (y 0..=3, z 1..=2)
        assert_eq!(h.value_range, [1.5, 3.5]);
        assert_eq!(h.counts, vec![8, 8]);
        let bad = Options {
            crop: Some([[0, 4], [0, 3], [0, 3]]),
            ..Options::default()
        };
        assert!(matches!(
            compute(&vol, Normalize::new(0.0, 3.0), &bad),
            Err(HistogramError::Crop { .. })
        ));
    }

    #[test]
    fn bad_options_and_data_are_errors() {
        let vol = volume(
            ScalarType::Float32,
            [2, 1, 1],
            [1.0; 3],
            &[f64::NAN, f64::NAN],
        );
        let norm = Normalize::new(0.0, 1.0);
        let e = compute(&vol, norm, &Options::default()).unwrap_err();
        assert!(e.to_string().contains("no finite values"), "{e}");
        for (opts, needle) in [
            (
                Options {
                    bins: 0,
                    ..Options::default()
                },
                "value bins",
            ),
            (
                Options {
                    bins: MAX_BINS + 1,
                    ..Options::default()
                },
                "value bins",
            ),
            (
                Options {
                    gradient_bins: 0,
                    ..Options::default()
                },
                "gradient bins",
            ),
            (
                Options {
                    gradient_max: Some(f64::NAN),
                    ..Options::default()
                },
                "gradient axis",
            ),
            (
                Options {
                    gradient_max: Some(0.0),
                    ..Options::default()
                },
                "gradient axis",
            ),
        ] {
            let e = compute(&vol, norm, &opts).unwrap_err().to_string();
            assert!(e.contains(needle), "{e}");
        }
        // a range whose width overflows is refused, not binned (nor plotted)
        let wide = volume(ScalarType::Float64, [2, 1, 1], [1.0; 3], &[-1e308, 1e308]);
        let e = compute(&wide, Normalize::new(-1e308, 1e308), &Options::default()).unwrap_err();
        assert!(e.to_string().contains("wider than can be binned"), "{e}");
        let mut h = compute(&vol_ok(), norm, &Options::default()).unwrap();
        h.value_range = [-1e308, 1e308];
        let e = plot::value_plot(&h, &Overlays::default(), "t").unwrap_err();
        assert!(e.to_string().contains("value axis"), "{e}");
        let mut flat = volume(ScalarType::Float32, [2, 1, 1], [1.0; 3], &[1.0, 2.0]);
        flat.header.geometry = Geometry::from_spacing([1.0, 0.0, 1.0]);
        let e = compute(&flat, norm, &Options::default()).unwrap_err();
        assert!(matches!(e, HistogramError::Geometry(_)), "{e}");
    }

    #[test]
    fn the_same_counts_for_any_number_of_threads() {
        let n = [17, 13, 11];
        let vol = volume(ScalarType::Float32, n, [1.0, 1.0, 2.0], &bumpy(n));
        let norm = Normalize::new(40.0, 170.0);
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| compute(&vol, norm, &Options::default()).unwrap())
        };
        assert_eq!(run(1), run(3));
    }

    #[test]
    fn data_values_undo_the_window_and_the_rescale() {
        let r = Rescale {
            slope: 2.0,
            intercept: -1000.0,
        };
        // physical window [-200, 600] is stored [400, 800]
        let [lo, hi] = r.stored_window([-200.0, 600.0]);
        let norm = Normalize::new(lo, hi);
        assert_eq!(data_value(norm, r, 0.0), -200.0);
        assert_eq!(data_value(norm, r, 1.0), 600.0);
        assert_eq!(data_value(norm, r, 0.25), 0.0);
    }
}
