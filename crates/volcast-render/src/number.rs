//! How messages and `volcast info` quote a number: as written for everyday
//! magnitudes, in exponent form where that would be a long run of digits or zeros,
//! and a value stored in single precision as that number. This module sits below
//! every layer that quotes numbers.

/// `x` as Rust prints it (the shortest form that reads back), in exponent form
/// outside 1e-6..1e15; a value that is exactly a single-precision number prints as
/// that number (a file's float32 3.2, not its double 3.200000047683716).
pub fn shown(x: f64) -> String {
    let plain = x == 0.0 || !x.is_finite() || (1e-6..1e15).contains(&x.abs());
    let single = x.is_finite() && f64::from(x as f32) == x;
    match (single, plain) {
        (true, true) => format!("{}", x as f32),
        (true, false) => format!("{:e}", x as f32),
        (false, true) => format!("{x}"),
        (false, false) => format!("{x:e}"),
    }
}

#[cfg(test)]
mod tests {
    use super::shown;

    #[test]
    fn numbers_are_quoted_short() {
        assert_eq!(shown(f64::from(3.2f32)), "3.2");
        assert_eq!(shown(0.1), "0.1");
        assert_eq!(shown(1e308), "1e308");
        assert_eq!(shown(-1.234567890123e-19), "-1.234567890123e-19");
        // a float32 axis component's rounding noise, as a NIfTI qform gives it
        assert_eq!(shown(f64::from(-6.7147157e-19f32)), "-6.7147157e-19");
        assert_eq!(shown(f64::MAX), "1.7976931348623157e308");
        assert_eq!(shown(3926.0), "3926");
        assert_eq!(shown(f64::NAN), "NaN");
    }
}
