//! Design answers drawn from sweep results.

/// Preload above which backlash flattens: the smallest preload at which the backlash is
/// within `tolerance` (e.g. 0.2 = 20 %) of its infinite-preload limit `asymptote`,
/// interpolated linearly between the swept preloads. `None` when no swept preload gets
/// there. `points` are `(preload N, backlash)` in any order; non-finite backlash (slack or
/// gross slip cases) is ignored.
pub fn flattening_preload(points: &[(f64, f64)], asymptote: f64, tolerance: f64) -> Option<f64> {
    let mut pts: Vec<(f64, f64)> = points
        .iter()
        .copied()
        .filter(|p| p.0.is_finite() && p.1.is_finite())
        .collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let limit = asymptote * (1.0 + tolerance);
    let first = pts.iter().position(|p| p.1 <= limit)?;
    if first == 0 {
        return Some(pts[0].0);
    }
    let (p0, b0) = pts[first - 1];
    let (p1, b1) = pts[first];
    if b0 == b1 {
        return Some(p1);
    }
    Some(p0 + (p1 - p0) * (b0 - limit) / (b0 - b1))
}

/// Least preload (N) at which `ok(preload)` holds, by bisection between `lo` and `hi`,
/// assuming `ok` is monotone (false below the answer, true above). `None` if even `hi`
/// fails.
pub fn least_preload(ok: impl Fn(f64) -> bool, lo: f64, hi: f64, tol: f64) -> Option<f64> {
    if !ok(hi) {
        return None;
    }
    if ok(lo) {
        return Some(lo);
    }
    let (mut a, mut b) = (lo, hi);
    while b - a > tol {
        let m = 0.5 * (a + b);
        if ok(m) {
            b = m;
        } else {
            a = m;
        }
    }
    Some(b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flattening_interpolates() {
        let pts = [(10.0, 3.0), (20.0, 1.5), (40.0, 1.1)];
        // limit 1.2 lies between 1.5 and 1.1 at three quarters of the way to 40.
        let p = flattening_preload(&pts, 1.0, 0.2).unwrap();
        assert!((p - 35.0).abs() < 1e-12);
        assert_eq!(flattening_preload(&pts, 0.5, 0.2), None);
    }

    #[test]
    fn least_preload_bisects() {
        let p = least_preload(|x| x >= 37.25, 1.0, 500.0, 1e-6).unwrap();
        assert!((p - 37.25).abs() < 1e-5);
        assert_eq!(least_preload(|_| false, 1.0, 2.0, 1e-3), None);
    }
}
