//! Safeguarded Newton (or Halley) iteration for the monotone tension equations.

/// Why no root was returned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RootError {
    /// The function is already positive at the lower end of its domain: no root exists
    /// there (for a cable half, the span would need a negative tension: slack).
    BelowDomain,
}

/// Root of `f`, strictly increasing on `(lower, inf)`, where `f` returns `(value,
/// derivative)`. Newton steps from `guess`, falling back to bisection inside the bracket;
/// `scale` sets the size of expansion steps and the absolute floor of the tolerance
/// `rtol * max(|x|, scale)`.
#[inline]
pub fn solve_increasing(
    mut f: impl FnMut(f64) -> (f64, f64),
    lower: f64,
    guess: f64,
    scale: f64,
    rtol: f64,
) -> Result<f64, RootError> {
    solve_increasing_curved(
        |x| {
            let (v, d) = f(x);
            (v, d, 0.0)
        },
        lower,
        guess,
        scale,
        rtol,
    )
}

/// [`solve_increasing`] for an `f` that also returns its second derivative: Halley steps
/// (cubic convergence), so a good guess lands within the tolerance after one step and the
/// root is confirmed by the second evaluation. Falls back to Newton where Halley's
/// denominator degenerates, and to bisection inside the bracket.
#[inline]
pub fn solve_increasing_curved(
    mut f: impl FnMut(f64) -> (f64, f64, f64),
    lower: f64,
    guess: f64,
    scale: f64,
    rtol: f64,
) -> Result<f64, RootError> {
    let floor = lower + 1e-9 * scale;
    let mut lo = lower;
    let mut lo_checked = false;
    let mut hi = f64::INFINITY;
    let mut x = if guess.is_finite() && guess > floor {
        guess
    } else {
        lower + 0.5 * scale
    };
    for _ in 0..200 {
        let (fx, dfx, d2fx) = f(x);
        if fx == 0.0 {
            return Ok(x);
        }
        if fx > 0.0 {
            hi = x;
        } else {
            lo = x;
            lo_checked = true;
        }
        let denominator = 2.0 * dfx * dfx - fx * d2fx;
        let mut next = if denominator > dfx * dfx {
            x - 2.0 * fx * dfx / denominator
        } else {
            x - fx / dfx
        };
        if !(next.is_finite() && next > lo && next < hi) {
            if !lo_checked && next <= lo {
                // The step leaves the domain: the root is either just above the lower end
                // or does not exist.
                if f(floor).0 > 0.0 {
                    return Err(RootError::BelowDomain);
                }
                lo = floor;
                lo_checked = true;
            }
            next = if hi.is_finite() {
                0.5 * (lo + hi)
            } else {
                (2.0 * x).max(x + scale)
            };
        }
        // x is within the tolerance of the root here; returning it (not the unevaluated
        // next iterate) lets callers reuse what they computed at x.
        if (next - x).abs() <= rtol * x.abs().max(scale) || hi - lo <= rtol * scale {
            return Ok(x);
        }
        x = next;
    }
    Ok(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_root_of_cubic_from_far_guesses() {
        for guess in [0.0, 1e-6, 0.5, 3.0, 100.0, 1e9] {
            let r = solve_increasing(|x| (x * x * x - 8.0, 3.0 * x * x), 0.0, guess, 1.0, 1e-14);
            assert!((r.unwrap() - 2.0).abs() < 1e-12, "guess {guess}");
        }
    }

    #[test]
    fn halley_finds_root_of_cubic_from_far_guesses() {
        for guess in [0.0, 1e-6, 0.5, 3.0, 100.0, 1e9] {
            let r = solve_increasing_curved(
                |x| (x * x * x - 8.0, 3.0 * x * x, 6.0 * x),
                0.0,
                guess,
                1.0,
                1e-14,
            );
            assert!((r.unwrap() - 2.0).abs() < 1e-12, "guess {guess}");
        }
    }

    #[test]
    fn reports_no_root_in_domain() {
        let r = solve_increasing(|x| (x + 1.0, 1.0), 0.0, 5.0, 1.0, 1e-12);
        assert_eq!(r, Err(RootError::BelowDomain));
    }
}
