//! Everything a pass needs before its first ray: the value normalisation, the
//! precomputed volumes and tables, the light and the per-ray kernel.

use super::*;

/// The normalisation of the scene's value window, or of the data's finite range.
pub fn value_window(scene: &Scene, volume: &Volume) -> Result<Normalize, Error> {
    if let Some([lo, hi]) = scene.volume.window {
        return Ok(Normalize::new(lo, hi));
    }
    let stats = Stats::of(&volume.data);
    if stats.finite == 0 {
        return Err(Error::Plan {
            scene: scene.path.clone(),
            message: format!(
                "the volume {} has no finite values to take a window from",
                volume.header.source
            ),
        });
    }
    let w = Window::from_range(stats.min, stats.max);
    Ok(Normalize::new(w.lo, w.hi))
}

impl Precomputed {
    pub(super) fn build<T: Voxel>(
        scene: &Scene,
        plan: &Plan,
        data: &[T],
        sizes: [usize; 3],
        norm: Normalize,
    ) -> Precomputed {
        let coefficients = plan
            .passes
            .iter()
            .any(|p| p.cubic)
            .then(|| prefilter_cubic(data, sizes, norm));
        let mut gradients: Vec<(GradientMethod, Vec<[f32; 3]>)> = Vec::new();
        for p in &plan.passes {
            if let Some(m) = p.gradient_volume {
                if !gradients.iter().any(|(g, _)| *g == m) {
                    gradients.push((m, gradient_volume(data, sizes, norm, m)));
                }
            }
        }
        let tables = scene
            .passes
            .iter()
            .map(|p| match &p.mode {
                Mode::Composite {
                    transfer: Transfer::OneD(t),
                    ..
                } => Some(OwnedTable::OneD(t.table(TABLE_1D))),
                Mode::Composite {
                    transfer: Transfer::TwoD(t),
                    ..
                } => Some(OwnedTable::TwoD(t.table(TABLE_2D, TABLE_2D))),
                _ => None,
            })
            .collect();
        Precomputed {
            coefficients,
            gradients,
            tables,
        }
    }
}

/// The light of the scene in renderer form.
pub(super) fn shade_light(scene: &Scene, centre: glam::DVec3) -> Light {
    let target = scene.camera.target.unwrap_or(centre);
    let l = &scene.light;
    let (kind, default_intensity) = match l.kind {
        LightKindSpec::Headlight => (LightKind::Headlight, 1.0),
        LightKindSpec::Directional(d) => (
            LightKind::Directional {
                direction: d.as_vec3(),
            },
            1.0,
        ),
        LightKindSpec::Point(p) => (
            LightKind::Point {
                position: p.as_vec3(),
            },
            (p - target).length_squared().max(1e-12),
        ),
    };
    Light {
        kind,
        color: l.color.as_vec3(),
        intensity: l.intensity.unwrap_or(default_intensity) as f32,
    }
}

pub(super) fn kernel<'a>(
    pass: &crate::scene::RenderPass,
    table: Option<&'a OwnedTable>,
    light: Light,
    voxel_length: f64,
) -> Kernel<'a> {
    use crate::render::integrator::{Exact, Integrand};
    use crate::scene::Integration;
    let shader = |s: &crate::scene::Shading| Shader {
        model: s.model,
        material: s.material,
        light,
    };
    let exact = match (&pass.mode, pass.integration) {
        (_, Integration::Sampled) => None,
        (Mode::Xray { output, mu }, _) => Some(Exact::Xray {
            output: *output,
            mu: *mu,
        }),
        (Mode::Mip, _) => Some(Exact::Mip),
        (Mode::Minip, _) => Some(Exact::Minip),
        (Mode::Average, _) => Some(Exact::Average),
        (Mode::Depth { threshold }, _) => Some(Exact::Depth {
            threshold: *threshold as f32,
        }),
        (Mode::Surface { iso, shading }, _) => Some(Exact::Surface {
            iso: *iso as f32,
            shader: shader(shading),
        }),
        // the scene rejects exact integration for the other modes
        _ => None,
    };
    let integrand = match (&pass.mode, exact) {
        (_, Some(e)) => Integrand::Exact(e),
        (Mode::Xray { output, mu }, None) => Integrand::Xray {
            output: *output,
            mu: *mu,
        },
        (Mode::Mip, None) => Integrand::Mip,
        (Mode::Minip, None) => Integrand::Minip,
        (Mode::Average, None) => Integrand::Average,
        (Mode::Lmip { threshold }, None) => Integrand::Lmip {
            threshold: *threshold as f32,
        },
        (Mode::Depth { threshold }, None) => Integrand::Depth {
            threshold: *threshold as f32,
        },
        (Mode::Surface { iso, shading }, None) => Integrand::Surface {
            iso: *iso as f32,
            shader: shader(shading),
        },
        (
            Mode::Composite {
                shading,
                reference_step_voxels,
                early_stop,
                transfer,
                preintegrated,
                ..
            },
            None,
        ) => Integrand::Composite {
            table: match table.expect("the plan builds a table for every composite pass") {
                OwnedTable::OneD(t) => TransferTable::OneD(t),
                OwnedTable::TwoD(t) => TransferTable::TwoD(t),
            },
            shader: shading.as_ref().map(shader),
            reference_step: reference_step_voxels * voxel_length,
            early_stop: *early_stop as f32,
            voxel_length,
            // built once per pass, for the pass's step (the plan counts its memory)
            preintegrated: match (preintegrated, transfer) {
                (true, Transfer::OneD(tf)) => {
                    Some(std::sync::Arc::new(crate::transfer::Preintegrated::build(
                        tf,
                        pass.step_voxels / reference_step_voxels,
                    )))
                }
                _ => None,
            },
        },
    };
    Kernel {
        integrand,
        // the pass's seed: a hash of its name, so each pass jitters differently
        jitter: pass.jitter.then(|| {
            pass.name.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
                (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
            })
        }),
    }
}
