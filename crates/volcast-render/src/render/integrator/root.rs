//! Bracketed root refinement shared by the sampled and the exact crossing searches.

/// Illinois false position (regula falsi with the stalled end's value halved) on
/// `g` over `[a, b]`, where `g(a) < 0 <= g(b)`. Falls back to bisection wherever the
/// secant leaves the open interval (including `g(a) == g(b)` and NaN), so it also
/// converges on jumps. Stops when `done(a, b)`, when `g` is exactly zero, or after
/// `max_evals` evaluations. Returns the upper end of the final bracket (a point
/// where `g >= 0`) and the number of evaluations.
pub fn illinois(
    g: impl Fn(f64) -> f64,
    (mut a, mut ga): (f64, f64),
    (mut b, mut gb): (f64, f64),
    done: impl Fn(f64, f64) -> bool,
    max_evals: u64,
) -> (f64, u64) {
    let mut side = 0i8;
    let mut evals = 0;
    while evals < max_evals && !done(a, b) {
        let mut s = a - ga * (b - a) / (gb - ga);
        if !(s > a && s < b) {
            s = 0.5 * (a + b);
        }
        let gs = g(s);
        evals += 1;
        if gs >= 0.0 {
            b = s;
            gb = gs;
            if side == 1 {
                ga *= 0.5;
            }
            side = 1;
        } else {
            a = s;
            ga = gs;
            if side == -1 {
                gb *= 0.5;
            }
            side = -1;
        }
        if gs == 0.0 {
            break;
        }
    }
    (b, evals)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn converges_on_smooth_roots_and_jumps() {
        let (t, n) = illinois(
            |t| t * t - 2.0,
            (0.0, -2.0),
            (2.0, 2.0),
            |a, b| b - a < 1e-14,
            100,
        );
        assert!((t - 2f64.sqrt()).abs() < 1e-12 && n < 20, "{t} after {n}");
        let step = |t: f64| if t >= 0.3 { 1.0 } else { -1.0 };
        let (t, _) = illinois(step, (0.0, -1.0), (1.0, 1.0), |a, b| b - a < 1e-9, 100);
        assert!(t >= 0.3 && t - 0.3 < 1e-9);
    }
}
