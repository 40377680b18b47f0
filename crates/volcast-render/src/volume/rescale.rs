//! A linear map from stored voxel values to the values they stand for: NIfTI's
//! `scl_slope` / `scl_inter`, DICOM's rescale slope and intercept (Hounsfield units of
//! a CT). Voxels stay in their stored type; the map is folded into the value window
//! (see [`Rescale::stored_window`]), so a scene's windows, thresholds and
//! transfer-function knots in `units = "data"` are the physical values.

/// `physical = slope * stored + intercept`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rescale {
    /// Multiplier (finite, non-zero).
    pub slope: f64,
    /// Offset added after the multiplication (finite).
    pub intercept: f64,
}

impl Default for Rescale {
    fn default() -> Self {
        Rescale::IDENTITY
    }
}

impl Rescale {
    /// The map of a volume whose stored values are its values.
    pub const IDENTITY: Rescale = Rescale {
        slope: 1.0,
        intercept: 0.0,
    };

    /// True for [`Rescale::IDENTITY`].
    pub fn is_identity(&self) -> bool {
        *self == Rescale::IDENTITY
    }

    /// The physical value of a stored value.
    pub fn apply(&self, stored: f64) -> f64 {
        if self.is_identity() {
            stored
        } else {
            self.slope * stored + self.intercept
        }
    }

    /// The stored values at the ends of the physical window `[lo, hi]`: a window to
    /// normalise stored voxels with, `t = (x - a) / (b - a)`, that gives every voxel
    /// the `t` its physical value has in `[lo, hi]`. Decreasing (`a > b`) for a
    /// negative slope. The identity returns `[lo, hi]` unchanged (same bits).
    pub fn stored_window(&self, [lo, hi]: [f64; 2]) -> [f64; 2] {
        if self.is_identity() {
            [lo, hi]
        } else {
            [
                (lo - self.intercept) / self.slope,
                (hi - self.intercept) / self.slope,
            ]
        }
    }

    /// The window, in stored values, that maps the physical range of stored values
    /// `[min, max]` to [0, 1]: `[min, max]`, or `[max, min]` for a negative slope
    /// (where the largest stored value is the smallest physical one).
    pub fn stored_range_window(&self, [min, max]: [f64; 2]) -> [f64; 2] {
        if self.slope < 0.0 {
            [max, min]
        } else {
            [min, max]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_fold_the_map() {
        let r = Rescale {
            slope: 2.0,
            intercept: -1024.0,
        };
        assert_eq!(r.apply(600.0), 176.0);
        assert_eq!(r.stored_window([-1024.0, 976.0]), [0.0, 1000.0]);
        let n = Rescale {
            slope: -0.5,
            intercept: 10.0,
        };
        let [a, b] = n.stored_window([0.0, 10.0]);
        assert_eq!([a, b], [20.0, 0.0]);
        // a stored value normalised by the folded window equals its physical value
        // normalised by the physical window
        let x = 6.0;
        assert_eq!((x - a) / (b - a), (n.apply(x) - 0.0) / 10.0);
        assert_eq!(n.stored_range_window([1.0, 3.0]), [3.0, 1.0]);
        assert_eq!(Rescale::IDENTITY.stored_window([0.1, 0.7]), [0.1, 0.7]);
    }
}
