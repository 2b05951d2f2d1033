//! `(zI - A)^-1 v` for the small state matrices of a loop, on the stack.
//!
//! The margins read the loop gain at some 4300 frequencies per operating point, and a
//! tolerance sweep reads them for every case. Through `DMatrix` each frequency cost heap
//! allocations and nalgebra's generic LU, whose complex arithmetic divides where a
//! reciprocal would do and multiplies by one to keep its `axpy` general. This is Gaussian
//! elimination with partial pivoting on `[zI - A | v]` in the state's own coordinates,
//! the pivot's reciprocal taken once with one real division: the same algorithm, so as
//! accurate (a unit test holds the two within 1e-13 of the solution's size times the
//! condition number on random systems), without the overhead. An orthogonal reduction to
//! Hessenberg form, computed once per loop, makes each frequency `O(n^2)` and was faster
//! still, but it mixes angles, speeds and currents whose entries span decades: measured
//! against a 40-digit reference on the shipped loops it lost one to two digits of `P(z)`,
//! balanced or not, for a few per cent of a sweep (`benches/README.md`).

use nalgebra::{Complex, DMatrix};

/// Largest state dimension solved here; larger plants take nalgebra's LU. The plant has
/// 4 states (both angles and speeds), 5 with a voltage amplifier, 2 more with a gyro.
pub const MAX_DIM: usize = 8;

/// A state matrix of at most [`MAX_DIM`] states, row by row, for its resolvent.
#[derive(Clone, Debug)]
pub struct StateMatrix {
    n: usize,
    a: [[f64; MAX_DIM]; MAX_DIM],
}

/// A solution of at most [`MAX_DIM`] components.
pub struct Solved {
    x: [Complex<f64>; MAX_DIM],
    n: usize,
}

impl Solved {
    /// The solution's components.
    pub fn as_slice(&self) -> &[Complex<f64>] {
        &self.x[..self.n]
    }
}

impl StateMatrix {
    /// The square matrix `a`, or `None` when it is larger than [`MAX_DIM`], not square
    /// or empty.
    pub fn of(a: &DMatrix<f64>) -> Option<Self> {
        let n = a.nrows();
        if n == 0 || n > MAX_DIM || a.ncols() != n {
            return None;
        }
        let mut out = StateMatrix {
            n,
            a: [[0.0; MAX_DIM]; MAX_DIM],
        };
        for i in 0..n {
            for j in 0..n {
                out.a[i][j] = a[(i, j)];
            }
        }
        Some(out)
    }

    /// `(zI - A)^-1 v`, or zeros where `zI - A` is singular (as nalgebra's LU gives
    /// it); `None` when `v` does not match the matrix.
    pub fn resolvent(&self, z: Complex<f64>, v: &[Complex<f64>]) -> Option<Solved> {
        if v.len() != self.n {
            return None;
        }
        // One copy per size, so that every loop has a fixed count.
        Some(match self.n {
            1 => self.sized::<1>(z, v),
            2 => self.sized::<2>(z, v),
            3 => self.sized::<3>(z, v),
            4 => self.sized::<4>(z, v),
            5 => self.sized::<5>(z, v),
            6 => self.sized::<6>(z, v),
            7 => self.sized::<7>(z, v),
            _ => self.sized::<8>(z, v),
        })
    }

    fn sized<const N: usize>(&self, z: Complex<f64>, v: &[Complex<f64>]) -> Solved {
        let zero = Complex::new(0.0, 0.0);
        let mut out = Solved {
            x: [zero; MAX_DIM],
            n: N,
        };
        let mut m = [[zero; N]; N];
        for (i, row) in m.iter_mut().enumerate() {
            for (j, e) in row.iter_mut().enumerate() {
                *e = Complex::from(-self.a[i][j]);
            }
            row[i] += z;
        }
        let mut w = [zero; N];
        w.copy_from_slice(v);
        let norm1 = |c: Complex<f64>| c.re.abs() + c.im.abs();
        let mut inv = [zero; N];
        for k in 0..N {
            // Partial pivoting as a running maximum: each row below that is larger in
            // this column trades places with the pivot row. The pivot ends up the
            // column's largest (the first of equals), as in a plain search, with no
            // index to carry from the search to the swap.
            for i in k + 1..N {
                if norm1(m[i][k]) > norm1(m[k][k]) {
                    let (top, bottom) = m.split_at_mut(i);
                    std::mem::swap(&mut top[k], &mut bottom[0]);
                    w.swap(k, i);
                }
            }
            let p = m[k][k];
            if p.re == 0.0 && p.im == 0.0 {
                // A zero column: singular.
                return out;
            }
            inv[k] = reciprocal(p);
            // Index loops over the one array, like the running maximum above: together
            // they took the margins of `eots_tracking` from 947 to 740 us (`cargo bench
            // --bench margins`) against the split borrows and iterators they replace.
            #[allow(clippy::needless_range_loop)]
            for i in k + 1..N {
                let l = m[i][k] * inv[k];
                for j in k + 1..N {
                    let t = m[k][j];
                    m[i][j] -= l * t;
                }
                let t = w[k];
                w[i] -= l * t;
            }
        }
        let mut y = [zero; N];
        for i in (0..N).rev() {
            let s = (i + 1..N).fold(w[i], |acc, j| acc - m[i][j] * y[j]);
            y[i] = s * inv[i];
        }
        out.x[..N].copy_from_slice(&y);
        out
    }
}

/// `1/c` with one real division. A pivot of a loop's `zI - A` lies within some ten
/// decades of one (`z - 1` is 3e-5 at 0.1 Hz and 20 kHz), far from the `1e+-154` where
/// `|c|^2` would overflow or underflow.
#[inline(always)]
fn reciprocal(c: Complex<f64>) -> Complex<f64> {
    let s = 1.0 / c.norm_sqr();
    Complex::new(c.re * s, -c.im * s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DVector;
    use rand::{Rng, SeedableRng};

    fn reference(a: &DMatrix<f64>, z: Complex<f64>, v: &[Complex<f64>]) -> Vec<Complex<f64>> {
        let n = a.nrows();
        let m = DMatrix::<Complex<f64>>::identity(n, n) * z - a.map(Complex::from);
        m.lu()
            .solve(&DVector::from_column_slice(v))
            .unwrap_or_else(|| DVector::zeros(n))
            .iter()
            .copied()
            .collect()
    }

    /// Against an independent implementation of the same algorithm: nalgebra's LU with
    /// partial pivoting on `zI - A`. Random matrices of every size with entries spread
    /// over three decades, `z` on the unit circle (the margins' case) and off it, and
    /// `zI - A` kept away from singular (smallest singular value over largest at least
    /// 1e-3), where both solutions agree to rounding times the condition number.
    #[test]
    fn agrees_with_the_general_lu() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(20261128);
        let mut worst = 0.0f64;
        let mut checked = 0;
        for trial in 0..6000 {
            let n = 1 + trial % MAX_DIM;
            let a = DMatrix::from_fn(n, n, |_, _| {
                let mag = 10f64.powf(rng.gen_range(-1.5..1.5));
                if rng.gen_bool(0.15) {
                    0.0
                } else if rng.gen_bool(0.5) {
                    mag
                } else {
                    -mag
                }
            });
            let r = if trial % 3 == 0 {
                rng.gen_range(0.2..3.0)
            } else {
                1.0
            };
            let z = Complex::from_polar(r, rng.gen_range(0.0..std::f64::consts::PI));
            let m = DMatrix::<Complex<f64>>::identity(n, n) * z - a.map(Complex::from);
            let sv = m.clone().svd(false, false).singular_values;
            let (smax, smin) = (sv.max(), sv.min());
            if smin < 1e-3 * smax {
                continue;
            }
            let v: Vec<Complex<f64>> = (0..n)
                .map(|_| Complex::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0)))
                .collect();
            let want = reference(&a, z, &v);
            let got = StateMatrix::of(&a)
                .expect("within the size")
                .resolvent(z, &v)
                .expect("matching size");
            let size = want.iter().map(|c| c.norm()).fold(0.0, f64::max);
            let err = want
                .iter()
                .zip(got.as_slice())
                .map(|(a, b)| (a - b).norm())
                .fold(0.0, f64::max);
            let rel = err / (size * smax / smin);
            worst = worst.max(rel);
            checked += 1;
        }
        assert!(checked > 3000, "only {checked} systems checked");
        assert!(
            worst < 1e-13,
            "worst error {worst:e} of the size times the condition"
        );
    }

    /// A matrix already upper triangular solves by back substitution alone, exactly as
    /// written out by hand; a singular `zI - A` gives zeros, as the LU path does.
    #[test]
    fn triangular_and_singular_cases() {
        let a = DMatrix::from_row_slice(2, 2, &[0.5, 2.0, 0.0, -0.25]);
        let z = Complex::new(1.0, 0.0);
        let v = [Complex::new(1.0, 0.0), Complex::new(0.0, 1.0)];
        let x = StateMatrix::of(&a).unwrap().resolvent(z, &v).unwrap();
        // (zI - A) = [[0.5, -2], [0, 1.25]]: x1 = i/1.25, x0 = (1 + 2 x1)/0.5.
        let x1 = Complex::new(0.0, 0.8);
        let x0 = (Complex::new(1.0, 0.0) + x1 * 2.0) / 0.5;
        assert!((x.as_slice()[1] - x1).norm() < 1e-15);
        assert!((x.as_slice()[0] - x0).norm() < 1e-15);
        let singular = DMatrix::from_row_slice(2, 2, &[1.0, 3.0, 0.0, 2.0]);
        let x = StateMatrix::of(&singular)
            .unwrap()
            .resolvent(z, &v)
            .unwrap();
        assert!(x.as_slice().iter().all(|c| c.re == 0.0 && c.im == 0.0));
        assert!(StateMatrix::of(&DMatrix::zeros(9, 9)).is_none());
        assert!(StateMatrix::of(&a).unwrap().resolvent(z, &v[..1]).is_none());
    }
}
