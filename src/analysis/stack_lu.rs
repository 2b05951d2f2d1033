//! `(zI - A)^-1 v` for the small state matrices of a loop, on the stack.
//!
//! The margins read the loop gain at some 4300 frequencies per operating point, and a
//! tolerance sweep reads them for every case: through `DMatrix` each frequency cost five
//! heap allocations and nalgebra's generic LU. This is the same LU, partial pivoting by
//! the largest `|re| + |im|`, with every complex operation written as nalgebra and
//! num-complex write it, in the same order, so its results are bit for bit those of
//! `(DMatrix::identity(n, n) * z - A).lu().solve(v)` (a unit test holds it to that over
//! random matrices, pivoting and singular ones included). Keeping the arithmetic exact is
//! what lets every margin, every sweep row and every report stay byte-identical.

use nalgebra::{Complex, DMatrix};

/// Largest state dimension solved here; larger plants take nalgebra's path. The plant has
/// 4 states (both angles and speeds), 5 with a voltage amplifier, 2 more with a gyro.
pub const MAX_DIM: usize = 8;

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

/// `(zI - a)^-1 v`, or zeros where the matrix is singular, as
/// `(DMatrix::identity(n, n) * z - a.map(Complex::from)).lu().solve(v)` gives it; `None`
/// when `a` is larger than [`MAX_DIM`] or `v` does not match it.
pub fn resolvent(a: &DMatrix<f64>, z: Complex<f64>, v: &[Complex<f64>]) -> Option<Solved> {
    let n = a.nrows();
    if a.ncols() != n || v.len() != n {
        return None;
    }
    // One copy per size, so that every loop has a fixed count and nothing larger than
    // the matrix is cleared.
    match n {
        1 => Some(sized::<1>(a, z, v)),
        2 => Some(sized::<2>(a, z, v)),
        3 => Some(sized::<3>(a, z, v)),
        4 => Some(sized::<4>(a, z, v)),
        5 => Some(sized::<5>(a, z, v)),
        6 => Some(sized::<6>(a, z, v)),
        7 => Some(sized::<7>(a, z, v)),
        8 => Some(sized::<8>(a, z, v)),
        _ => None,
    }
}

fn sized<const N: usize>(a: &DMatrix<f64>, z: Complex<f64>, v: &[Complex<f64>]) -> Solved {
    let one = Complex::new(1.0, 0.0);
    // `identity * z` multiplies every entry, the zeros included, whose signs can follow z's.
    let (on, off) = (one * z, Complex::new(0.0, 0.0) * z);
    // Column-major, as nalgebra stores it: m[col][row].
    let mut m = [[Complex::new(0.0, 0.0); N]; N];
    for (j, col) in m.iter_mut().enumerate() {
        for (i, e) in col.iter_mut().enumerate() {
            *e = if i == j { on } else { off } - Complex::from(a[(i, j)]);
        }
    }
    let mut x = [Complex::new(0.0, 0.0); N];
    x.copy_from_slice(v);
    let mut perm = [(0usize, 0usize); N];
    let swaps = decompose(&mut m, &mut perm);
    let mut out = Solved {
        x: [Complex::new(0.0, 0.0); MAX_DIM],
        n: N,
    };
    if solve(&m, &perm[..swaps], &mut x) {
        out.x[..N].copy_from_slice(&x);
    }
    out
}

/// `y = a x c + b y` with `c = b = 1`, as nalgebra's `axpy` computes it.
#[inline(always)]
fn axpy(a: Complex<f64>, x: Complex<f64>, y: Complex<f64>) -> Complex<f64> {
    let one = Complex::new(1.0, 0.0);
    a * x * one + one * y
}

fn is_zero(c: Complex<f64>) -> bool {
    c.re == 0.0 && c.im == 0.0
}

/// nalgebra's `LU::new`: for each column the pivot is the first row of largest
/// `|re| + |im|` at or below the diagonal; a column with a zero pivot is left as it is.
/// Returns the number of row swaps recorded in `perm`.
fn decompose<const N: usize>(
    m: &mut [[Complex<f64>; N]; N],
    perm: &mut [(usize, usize); N],
) -> usize {
    let n = N;
    let mut swaps = 0;
    let one = Complex::new(1.0, 0.0);
    let norm1 = |c: Complex<f64>| c.re.abs() + c.im.abs();
    for i in 0..n {
        let mut piv = i;
        let mut best = norm1(m[i][i]);
        for (r, c) in m[i].iter().enumerate().skip(i + 1) {
            let v = norm1(*c);
            if v > best {
                best = v;
                piv = r;
            }
        }
        let diag = m[i][piv];
        if is_zero(diag) {
            continue;
        }
        if piv != i {
            perm[swaps] = (i, piv);
            swaps += 1;
            for col in m.iter_mut().take(i) {
                col.swap(i, piv);
            }
            m[i].swap(i, piv);
        }
        let inv_diag = one / diag;
        for c in m[i].iter_mut().skip(i + 1) {
            *c *= inv_diag;
        }
        let (left, right) = m.split_at_mut(i + 1);
        let coeffs = &left[i];
        for col in right.iter_mut().take(n - i - 1) {
            col.swap(i, piv);
            let a = -col[i];
            for r in i + 1..n {
                col[r] = axpy(a, coeffs[r], col[r]);
            }
        }
    }
    swaps
}

/// nalgebra's `LU::solve_mut`: the row swaps, the unit lower triangle, the upper one;
/// `false` where a diagonal of the upper triangle is zero.
fn solve<const N: usize>(
    m: &[[Complex<f64>; N]; N],
    perm: &[(usize, usize)],
    x: &mut [Complex<f64>; N],
) -> bool {
    let n = N;
    let one = Complex::new(1.0, 0.0);
    for &(a, b) in perm {
        x.swap(a, b);
    }
    for i in 0..n.saturating_sub(1) {
        let a = -(x[i] / one);
        for r in i + 1..n {
            x[r] = axpy(a, m[i][r], x[r]);
        }
    }
    for i in (0..n).rev() {
        let diag = m[i][i];
        if is_zero(diag) {
            return false;
        }
        let coeff = x[i] / diag;
        x[i] = coeff;
        let a = -coeff;
        for r in 0..i {
            x[r] = axpy(a, m[i][r], x[r]);
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DVector;
    use rand::{Rng, SeedableRng};

    fn reference(a: &DMatrix<f64>, z: Complex<f64>, v: &[Complex<f64>]) -> Vec<Complex<f64>> {
        let n = a.nrows();
        let m = DMatrix::<Complex<f64>>::identity(n, n) * z - a.map(Complex::from);
        let v = DVector::from_column_slice(v);
        m.lu()
            .solve(&v)
            .unwrap_or_else(|| DVector::zeros(n))
            .iter()
            .copied()
            .collect()
    }

    fn same_bits(a: &[Complex<f64>], b: &[Complex<f64>]) -> bool {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(x, y)| x.re.to_bits() == y.re.to_bits() && x.im.to_bits() == y.im.to_bits())
    }

    /// Random matrices of every size up to the largest, with entries spread over many
    /// decades, exact zeros (signed), a repeated column, and `z` on and off the
    /// unit circle: the solution is nalgebra's bit for bit, signs of zero included.
    #[test]
    fn the_solution_is_nalgebras_bit_for_bit() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let mut checked = 0;
        for trial in 0..8000 {
            let n = 1 + trial % MAX_DIM;
            let mut a = DMatrix::<f64>::from_fn(n, n, |_, _| {
                let mag = 10f64.powf(rng.gen_range(-6.0..6.0));
                let v = if rng.gen_bool(0.5) { mag } else { -mag };
                match rng.gen_range(0..10) {
                    0 => 0.0,
                    1 => -0.0,
                    2 => 1.0,
                    _ => v,
                }
            });
            if trial % 7 == 0 && n > 1 {
                // A repeated column makes the matrix singular at z = 0.
                let c = a.column(0).into_owned();
                a.set_column(n - 1, &c);
            }
            let theta = match trial % 5 {
                0 => 0.0,
                1 => std::f64::consts::PI,
                _ => rng.gen_range(-4.0..4.0),
            };
            let radius = if trial % 3 == 0 { 0.0 } else { 1.0 };
            let z = Complex::from_polar(radius, theta);
            let v: Vec<Complex<f64>> = (0..n)
                .map(|k| {
                    if k % 4 == 3 {
                        Complex::new(0.0, -0.0)
                    } else {
                        Complex::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0))
                    }
                })
                .collect();
            let got = resolvent(&a, z, &v).expect("within the size");
            let want = reference(&a, z, &v);
            assert!(
                same_bits(got.as_slice(), &want),
                "trial {trial}, n {n}: {:?} against {want:?}",
                got.as_slice()
            );
            checked += 1;
        }
        assert_eq!(checked, 8000);
    }

    /// A matrix of zeros with z = 0 is singular everywhere: zeros, as nalgebra's path
    /// gives through `unwrap_or_else`.
    #[test]
    fn a_singular_matrix_gives_zeros() {
        let a = DMatrix::<f64>::zeros(3, 3);
        let v = [Complex::new(1.0, 2.0); 3];
        let got = resolvent(&a, Complex::new(0.0, 0.0), &v).expect("within the size");
        assert!(got.as_slice().iter().all(|c| c.re == 0.0 && c.im == 0.0));
    }

    #[test]
    fn too_large_or_mismatched_is_declined() {
        let a = DMatrix::<f64>::zeros(MAX_DIM + 1, MAX_DIM + 1);
        let v = vec![Complex::new(1.0, 0.0); MAX_DIM + 1];
        assert!(resolvent(&a, Complex::new(1.0, 0.0), &v).is_none());
        let a = DMatrix::<f64>::zeros(3, 3);
        assert!(resolvent(&a, Complex::new(1.0, 0.0), &v[..2]).is_none());
    }
}
