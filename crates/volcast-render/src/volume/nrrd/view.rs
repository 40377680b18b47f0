//! The 3D view of an N-D header: which axes become x, y, z, and the index-to-world
//! geometry (space directions + origin, or spacings).

use crate::volume::errors::{header_err, unsupported};
use std::path::Path;

use glam::DVec3;

use crate::volume::{Geometry, VolumeError, VolumeHeader};
use ::nrrd::NrrdHeader;

/// True when axis `i` is not a spatial axis (a `none` direction or a non-domain kind).
fn non_spatial(h: &NrrdHeader, i: usize) -> bool {
    let none_dir = h.space_directions.as_ref().is_some_and(|d| d[i].is_none());
    let kind = h.kinds.as_ref().map(|k| k[i].to_ascii_lowercase());
    let non_domain_kind =
        kind.is_some_and(|k| !matches!(k.as_str(), "domain" | "space" | "time" | "???" | "none"));
    none_dir || non_domain_kind
}

/// The (at most 3) axes that become x, y, z: all of them up to dimension 3; above,
/// size-1 axes are dropped, non-spatial ones first, then from the slowest axis.
fn kept_axes(h: &NrrdHeader, path: &Path) -> Result<Vec<usize>, VolumeError> {
    let dim = h.dimension();
    let mut kept: Vec<usize> = (0..dim).collect();
    if dim <= 3 {
        return Ok(kept);
    }
    let mut drop: Vec<usize> = (0..dim)
        .filter(|&i| h.sizes[i] == 1 && non_spatial(h, i))
        .collect();
    drop.extend(
        (0..dim)
            .rev()
            .filter(|&i| h.sizes[i] == 1 && !non_spatial(h, i)),
    );
    if drop.len() < dim - 3 {
        return Err(unsupported(
            path,
            format!(
                "dimension {dim} with sizes {:?}: only 3 axes can be rendered, and only axes of size 1 can be dropped",
                h.sizes
            ),
        ));
    }
    drop.truncate(dim - 3);
    kept.retain(|i| !drop.contains(i));
    Ok(kept)
}

/// A unit vector completing a frame where an axis has no direction.
fn fill_axis(axes: &[Option<DVec3>; 3], planar: bool) -> DVec3 {
    if planar {
        return DVec3::Z;
    }
    let known: Vec<DVec3> = axes.iter().flatten().copied().collect();
    match known.as_slice() {
        [a, b] => a.cross(*b).normalize_or_zero(),
        [a] => a.any_orthonormal_vector(),
        _ => DVec3::X,
    }
}

/// A 2- or 3-component vector as a 3D one (z = 0 for 2D); checked lengths.
fn vec3(v: &[f64]) -> DVec3 {
    let c = |i: usize, default: f64| v.get(i).copied().unwrap_or(default);
    DVec3::new(c(0, f64::NAN), c(1, f64::NAN), c(2, 0.0))
}

/// Geometry from `space directions` (and `space origin`).
fn geometry_from_directions(
    h: &NrrdHeader,
    kept: &[usize],
    path: &Path,
) -> Result<Geometry, VolumeError> {
    let dirs = h.space_directions.as_deref().unwrap_or_default();
    let sd = h.space_dimension.unwrap_or(0);
    let vectors_fit = dirs
        .iter()
        .flatten()
        .chain(&h.space_origin)
        .all(|v| v.len() == sd);
    if !vectors_fit {
        return Err(header_err(
            path,
            format!("space directions and origin must have {sd} components (space dimension {sd})"),
        ));
    }
    let planar = match sd {
        3 => false,
        2 if kept.iter().filter(|&&i| dirs[i].is_some()).count() <= 2 => true,
        _ => {
            return Err(unsupported(
                path,
                format!(
                    "space dimension {sd}: a volume needs a 3-D space (or a 2-D space for 2-D data)"
                ),
            ))
        }
    };
    let mut axes: [Option<DVec3>; 3] = [None; 3];
    for (slot, &i) in kept.iter().enumerate() {
        match &dirs[i] {
            Some(v) => axes[slot] = Some(vec3(v)),
            None if h.sizes[i] == 1 => {}
            None => {
                return Err(unsupported(
                    path,
                    format!(
                        "axis {i} (size {}) has space direction `none`: a non-spatial axis cannot be rendered as a volume axis",
                        h.sizes[i]
                    ),
                ))
            }
        }
    }
    let filled: Vec<DVec3> = (0..3)
        .map(|s| axes[s].unwrap_or_else(|| fill_axis(&axes, planar)))
        .collect();
    let origin = h.space_origin.as_deref().map_or(DVec3::ZERO, vec3);
    Ok(Geometry {
        origin,
        axes: [filled[0], filled[1], filled[2]],
    })
}

/// Geometry from `spacings` (nan or missing → 1) and the origin, if any.
fn geometry_from_spacings(h: &NrrdHeader, kept: &[usize]) -> Geometry {
    let mut spacing = [1.0; 3];
    for (slot, &i) in kept.iter().enumerate() {
        if let Some(s) = h.spacings.as_ref().map(|s| s[i]).filter(|s| s.is_finite()) {
            spacing[slot] = s;
        }
    }
    let mut g = Geometry::from_spacing(spacing);
    if let Some(o) = h
        .space_origin
        .as_deref()
        .filter(|o| (2..=3).contains(&o.len()))
    {
        g.origin = vec3(o);
    }
    g
}

/// Descriptive fields for display.
fn display_fields(h: &NrrdHeader) -> Vec<(String, String)> {
    let mut f = Vec::new();
    if let Some(c) = &h.content {
        f.push(("content".into(), c.clone()));
    }
    if let Some(s) = h.space {
        f.push(("space".into(), s.name().into()));
    }
    if let Some(u) = &h.space_units {
        f.push(("space units".into(), u.join(" ")));
    }
    if let Some(u) = &h.units {
        f.push(("units".into(), u.join(" ")));
    }
    if let Some(u) = &h.sample_units {
        f.push(("sample units".into(), u.clone()));
    }
    f.extend(h.key_values.iter().cloned());
    f
}

/// Per-axis lists must have one entry per axis (always true for parsed headers; this
/// guards headers built in code).
fn check_lengths(h: &NrrdHeader, path: &Path) -> Result<(), VolumeError> {
    let dim = h.dimension();
    let fits = |n: Option<usize>| n.is_none_or(|n| n == dim);
    let ok = (1..=16).contains(&dim)
        && fits(h.space_directions.as_ref().map(Vec::len))
        && fits(h.kinds.as_ref().map(Vec::len))
        && fits(h.spacings.as_ref().map(Vec::len));
    if ok {
        Ok(())
    } else {
        Err(header_err(
            path,
            format!(
                "sizes {:?}: space directions, kinds and spacings need one entry per axis",
                h.sizes
            ),
        ))
    }
}

/// See [`NrrdHeader::volume_header`].
pub(super) fn volume_header(h: &NrrdHeader, path: &Path) -> Result<VolumeHeader, VolumeError> {
    check_lengths(h, path)?;
    let kept = kept_axes(h, path)?;
    let mut sizes = [1usize; 3];
    for (slot, &i) in kept.iter().enumerate() {
        sizes[slot] = h.sizes[i];
    }
    let geometry = if h.space_directions.is_some() {
        geometry_from_directions(h, &kept, path)?
    } else {
        geometry_from_spacings(h, &kept)
    };
    if !geometry.is_valid() {
        return Err(header_err(
            path,
            format!(
                "degenerate geometry: axis vectors {:?}, {:?}, {:?} and origin {:?} must be finite, non-zero and independent",
                geometry.axes[0].to_array(),
                geometry.axes[1].to_array(),
                geometry.axes[2].to_array(),
                geometry.origin.to_array()
            ),
        ));
    }
    Ok(VolumeHeader {
        sizes,
        scalar_type: h.scalar_type,
        geometry,
        source: path.display().to_string(),
        fields: display_fields(h),
        rescale: Default::default(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::ScalarType;

    fn p() -> &'static Path {
        Path::new("v.nrrd")
    }

    #[test]
    fn two_d_becomes_one_slice() {
        let h = NrrdHeader::new(ScalarType::Float32, vec![5, 4]).with_spacings([2.0, 3.0]);
        let v = volume_header(&h, p()).unwrap();
        assert_eq!(v.sizes, [5, 4, 1]);
        assert_eq!(v.geometry, Geometry::from_spacing([2.0, 3.0, 1.0]));
    }

    #[test]
    fn drops_leading_non_spatial_size_one_axis() {
        let mut h = NrrdHeader::new(ScalarType::Uint8, vec![1, 4, 5, 6])
            .with_kinds(["scalar", "space", "space", "space"]);
        assert_eq!(volume_header(&h, p()).unwrap().sizes, [4, 5, 6]);
        h.kinds = None;
        h.sizes = vec![4, 5, 6, 1];
        assert_eq!(volume_header(&h, p()).unwrap().sizes, [4, 5, 6]);
        h.sizes = vec![4, 5, 6, 2];
        assert!(matches!(
            volume_header(&h, p()),
            Err(VolumeError::Unsupported { .. })
        ));
    }

    #[test]
    fn planar_space_embeds_at_z0() {
        let mut h = NrrdHeader::new(ScalarType::Uint8, vec![3, 2]);
        h.space_dimension = Some(2);
        h.space_directions = Some(vec![Some(vec![0.5, 0.0]), Some(vec![0.0, 2.0])]);
        h.space_origin = Some(vec![1.0, -1.0]);
        let g = volume_header(&h, p()).unwrap().geometry;
        assert_eq!(
            g.axes,
            [
                DVec3::new(0.5, 0.0, 0.0),
                DVec3::new(0.0, 2.0, 0.0),
                DVec3::Z
            ]
        );
        assert_eq!(g.origin, DVec3::new(1.0, -1.0, 0.0));
    }

    #[test]
    fn degenerate_geometry_is_a_header_error() {
        let mut h = NrrdHeader::new(ScalarType::Uint8, vec![2, 2, 2]);
        h.space_dimension = Some(3);
        h.space_directions = Some(vec![
            Some(vec![1.0, 0.0, 0.0]),
            Some(vec![2.0, 0.0, 0.0]),
            Some(vec![0.0, 0.0, 1.0]),
        ]);
        let e = volume_header(&h, p()).unwrap_err();
        assert!(matches!(e, VolumeError::Header { .. }), "{e}");
        assert!(
            e.to_string().starts_with("v.nrrd: degenerate geometry"),
            "{e}"
        );
    }

    #[test]
    fn inconsistent_headers_built_in_code_are_errors() {
        let h = NrrdHeader::new(ScalarType::Uint8, vec![2, 2, 2]).with_kinds(["RGBA-color"]);
        assert!(volume_header(&h, p()).is_err());
        let mut h = NrrdHeader::new(ScalarType::Uint8, vec![2, 2, 2]);
        h.space_dimension = Some(3);
        h.space_directions = Some(vec![Some(vec![1.0]), Some(vec![0.0, 1.0, 0.0]), None]);
        assert!(volume_header(&h, p()).is_err());
        assert!(volume_header(&NrrdHeader::new(ScalarType::Uint8, vec![]), p()).is_err());
    }

    #[test]
    fn none_direction_on_size_one_axis_is_completed() {
        let mut h = NrrdHeader::new(ScalarType::Uint8, vec![1, 3, 3]);
        h.space_dimension = Some(3);
        h.space_directions = Some(vec![
            None,
            Some(vec![1.0, 0.0, 0.0]),
            Some(vec![0.0, 1.0, 0.0]),
        ]);
        let g = volume_header(&h, p()).unwrap().geometry;
        assert_eq!(g.axes[0], DVec3::Z);
        h.sizes[0] = 3;
        assert!(volume_header(&h, p()).is_err());
    }
}
