//! The rotation that best maps one set of directions onto another (Horn's closed form), and
//! the largest eigenvector of a symmetric 4x4 matrix it needs.

use glam::{DQuat, Quat, Vec3};

/// The rotation `R` minimising `sum |R rest - actual|^2` (Horn 1987, closed form with
/// quaternions).
pub(super) fn horn(pairs: &[(Vec3, Vec3)]) -> Quat {
    let v = largest_eigenvector(horn_matrix(pairs));
    DQuat::from_xyzw(v[1], v[2], v[3], v[0]).normalize().as_quat()
}

/// Horn's symmetric 4x4 matrix of the (rest, actual) pairs, whose eigenvector of the largest
/// eigenvalue is the best rotation's quaternion (w, x, y, z).
pub(super) fn horn_matrix(pairs: &[(Vec3, Vec3)]) -> [[f64; 4]; 4] {
    let mut s = [[0f64; 3]; 3];
    for (r, d) in pairs {
        for (a, row) in s.iter_mut().enumerate() {
            for (b, v) in row.iter_mut().enumerate() {
                *v += r[a] as f64 * d[b] as f64;
            }
        }
    }
    let [[sxx, sxy, sxz], [syx, syy, syz], [szx, szy, szz]] = s;
    [
        [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
        [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
        [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
        [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz],
    ]
}

/// The eigenvector of the largest eigenvalue of Horn's matrix (symmetric, traceless, 4x4).
///
/// The largest root of the characteristic polynomial by Newton's method from above (the
/// Frobenius norm bounds every eigenvalue, and from right of a real-rooted polynomial's largest
/// root Newton descends onto it without overshooting), then the eigenvector as the longest
/// column of the adjugate of `N - lambda I` (rank 3 at a simple eigenvalue, so every nonzero
/// column is the eigenvector). That is a few dozen operations where Jacobi's sweeps were
/// hundreds, the rotation solve's largest cost. A (nearly) repeated largest eigenvalue leaves
/// the adjugate (nearly) zero and the eigenvector ill-defined from it: Jacobi then.
pub(super) fn largest_eigenvector(n: [[f64; 4]; 4]) -> [f64; 4] {
    let n2 = mul4(&n, &n);
    let p2: f64 = (0..4).map(|i| n2[i][i]).sum();
    let p3: f64 = (0..4).map(|i| (0..4).map(|k| n2[i][k] * n[k][i]).sum::<f64>()).sum();
    let (a, b, c) = (-0.5 * p2, -p3 / 3.0, det4(&n));
    let norm = p2.sqrt();
    if !norm.is_finite() || norm <= f64::MIN_POSITIVE {
        return jacobi_largest_eigenvector(n);
    }
    let mut lambda = norm;
    for _ in 0..50 {
        let value = ((lambda * lambda + a) * lambda + b) * lambda + c;
        let slope = (4.0 * lambda * lambda + 2.0 * a) * lambda + b;
        if slope <= 0.0 {
            break;
        }
        let step = value / slope;
        lambda -= step;
        if step.abs() <= 1e-15 * norm {
            break;
        }
    }
    let mut shifted = n;
    for (i, row) in shifted.iter_mut().enumerate() {
        row[i] -= lambda;
    }
    // adj(B) is symmetric with diagonal v_i^2 times a constant: the column of the largest
    // diagonal cofactor is the best conditioned.
    let best = (0..4).map(|i| (i, cofactor(&shifted, i, i))).fold((0, f64::MIN), |b, (i, d)| if d.abs() > b.1.abs() { (i, d) } else { b }).0;
    let v: [f64; 4] = std::array::from_fn(|k| cofactor(&shifted, k, best));
    let length = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    if length.is_nan() || length <= 1e-6 * norm * norm * norm {
        return jacobi_largest_eigenvector(n);
    }
    v.map(|x| x / length)
}

fn mul4(a: &[[f64; 4]; 4], b: &[[f64; 4]; 4]) -> [[f64; 4]; 4] {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..4).map(|k| a[i][k] * b[k][j]).sum()))
}

/// The (row, col) cofactor of a 4x4 matrix: the signed determinant of the 3x3 left without them.
fn cofactor(m: &[[f64; 4]; 4], row: usize, col: usize) -> f64 {
    let rows: [usize; 3] = std::array::from_fn(|k| if k < row { k } else { k + 1 });
    let cols: [usize; 3] = std::array::from_fn(|k| if k < col { k } else { k + 1 });
    let e = |r: usize, c: usize| m[rows[r]][cols[c]];
    let minor = e(0, 0) * (e(1, 1) * e(2, 2) - e(1, 2) * e(2, 1)) - e(0, 1) * (e(1, 0) * e(2, 2) - e(1, 2) * e(2, 0)) + e(0, 2) * (e(1, 0) * e(2, 1) - e(1, 1) * e(2, 0));
    if (row + col).is_multiple_of(2) { minor } else { -minor }
}

fn det4(m: &[[f64; 4]; 4]) -> f64 {
    (0..4).map(|k| m[0][k] * cofactor(m, 0, k)).sum()
}

/// The eigenvector of the largest eigenvalue of a symmetric 4x4 matrix (cyclic Jacobi).
pub(super) fn jacobi_largest_eigenvector(mut a: [[f64; 4]; 4]) -> [f64; 4] {
    let mut v = [[0f64; 4]; 4];
    for (i, row) in v.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    let norm: f64 = a.iter().flatten().map(|x| x * x).sum();
    for _sweep in 0..30 {
        let off: f64 = (0..4).flat_map(|p| (0..4).filter(move |&q| q != p).map(move |q| (p, q))).map(|(p, q)| a[p][q] * a[p][q]).sum();
        if off.is_nan() || off <= 1e-30 * norm {
            break;
        }
        for p in 0..3 {
            for q in p + 1..4 {
                if a[p][q].abs() < 1e-300 {
                    continue;
                }
                let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                let t = if theta >= 0.0 { 1.0 } else { -1.0 } / (theta.abs() + (theta * theta + 1.0).sqrt());
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for row in a.iter_mut() {
                    let (kp, kq) = (row[p], row[q]);
                    row[p] = c * kp - s * kq;
                    row[q] = s * kp + c * kq;
                }
                let (rp, rq) = (a[p], a[q]);
                a[p] = std::array::from_fn(|k| c * rp[k] - s * rq[k]);
                a[q] = std::array::from_fn(|k| s * rp[k] + c * rq[k]);
                for row in v.iter_mut() {
                    let (kp, kq) = (row[p], row[q]);
                    row[p] = c * kp - s * kq;
                    row[q] = s * kp + c * kq;
                }
            }
        }
    }
    let best = (0..4).fold(0, |b, i| if a[i][i] > a[b][b] { i } else { b });
    [v[0][best], v[1][best], v[2][best], v[3][best]]
}
