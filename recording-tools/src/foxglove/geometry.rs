//! A position covariance as the scaled, rotated sphere Foxglove draws: the
//! k-σ ellipsoid (an ellipse disc in 2-D) as diameters along the principal
//! axes and the rotation that takes the x, y, z axes onto them.

use nalgebra::{Matrix2, Matrix3, Rotation3, SymmetricEigen, UnitQuaternion, Vector3};

/// The ellipsoid of a covariance: `size[i]` is the diameter along the i-th
/// principal axis (largest first), `orientation` rotates the x axis onto the
/// major axis (and y, z onto the others). Foxglove's `SpherePrimitive` takes
/// exactly this: `size` along its local axes, `pose.orientation`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ellipsoid {
    pub size: [f64; 3],
    pub orientation: UnitQuaternion<f64>,
}

/// The principal axes of the leading `dim × dim` block (`dim` = 2 or 3) of
/// `cov`: eigenvalues largest first (negative round-off clamped to 0) and
/// the eigenvectors as the columns of a proper rotation (det +1). In 2-D the
/// third axis is z. `None` if an entry is not finite.
pub fn principal_axes(cov: &Matrix3<f64>, dim: usize) -> Option<([f64; 3], Matrix3<f64>)> {
    if dim == 2 {
        let c = Matrix2::new(cov[(0, 0)], cov[(0, 1)], cov[(1, 0)], cov[(1, 1)]);
        if c.iter().any(|v| !v.is_finite()) {
            return None;
        }
        // Symmetrise: the recorded covariance is symmetric up to round-off
        // and the solver reads only one triangle.
        let e = SymmetricEigen::new((c + c.transpose()) * 0.5);
        let (major, minor) = if e.eigenvalues[0] >= e.eigenvalues[1] {
            (0, 1)
        } else {
            (1, 0)
        };
        let v = e.eigenvectors.column(major);
        // The minor axis is the major one turned by +90°: with z that makes
        // the frame right-handed whatever sign the solver gave the vectors.
        #[rustfmt::skip]
        let r = Matrix3::new(
            v[0], -v[1], 0.0,
            v[1], v[0], 0.0,
            0.0, 0.0, 1.0,
        );
        let l = [
            e.eigenvalues[major].max(0.0),
            e.eigenvalues[minor].max(0.0),
            0.0,
        ];
        return Some((l, r));
    }
    if cov.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let e = SymmetricEigen::new((cov + cov.transpose()) * 0.5);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| e.eigenvalues[b].total_cmp(&e.eigenvalues[a]));
    let mut r = Matrix3::from_columns(&[
        e.eigenvectors.column(order[0]).into_owned(),
        e.eigenvectors.column(order[1]).into_owned(),
        e.eigenvectors.column(order[2]).into_owned(),
    ]);
    if r.determinant() < 0.0 {
        // A reflection is no rotation: flipping the least axis keeps the
        // same ellipsoid and makes det +1.
        r.set_column(2, &(-r.column(2)));
    }
    let l = order.map(|i| e.eigenvalues[i].max(0.0));
    Some((l, r))
}

/// The `k`-σ ellipsoid of a position covariance (`dim` = 2: an ellipse in the
/// xy plane drawn as a disc of thickness `flat`).
pub fn ellipsoid(cov: &Matrix3<f64>, dim: usize, k: f64, flat: f64) -> Option<Ellipsoid> {
    let (l, r) = principal_axes(cov, dim)?;
    let diameter = |l: f64| 2.0 * k * l.sqrt();
    let size = if dim == 2 {
        [diameter(l[0]), diameter(l[1]), flat]
    } else {
        l.map(diameter)
    };
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    // Re-normalise: the eigenvectors are orthonormal only to round-off.
    let orientation = UnitQuaternion::new_normalize(q.into_inner());
    Some(Ellipsoid { size, orientation })
}

/// The first three coordinates of a wire vector (z = 0 in 2-D).
pub fn point3(v: &[f64], dim: usize) -> Vector3<f64> {
    Vector3::from_fn(|i, _| {
        if i < dim {
            v.get(i).copied().unwrap_or(0.0)
        } else {
            0.0
        }
    })
}

/// The leading block (at most 3 × 3) of a wire matrix, zero-padded.
pub fn block3(m: &[[f64; 6]; 6], dim: usize) -> Matrix3<f64> {
    Matrix3::from_fn(|r, c| if r < dim && c < dim { m[r][c] } else { 0.0 })
}

#[cfg(test)]
mod tests {
    use super::*;

    const K: f64 = 3.0;

    fn parallel(a: &Vector3<f64>, b: &Vector3<f64>) -> bool {
        (a.normalize().dot(&b.normalize()).abs() - 1.0).abs() < 1e-9
    }

    /// R diag((size/2k)²) Rᵀ: the covariance the drawn ellipsoid stands for.
    fn rebuilt(e: &Ellipsoid, dim: usize) -> Matrix3<f64> {
        let r = e.orientation.to_rotation_matrix().into_inner();
        let mut d = Matrix3::zeros();
        for i in 0..dim {
            d[(i, i)] = (e.size[i] / (2.0 * K)).powi(2);
        }
        r * d * r.transpose()
    }

    #[test]
    fn diagonal_2d_keeps_the_axes() {
        let cov = Matrix3::new(4.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0);
        let e = ellipsoid(&cov, 2, K, 0.01).expect("finite");
        assert_eq!(e.size, [12.0, 6.0, 0.01]);
        assert!((e.orientation.norm() - 1.0).abs() < 1e-12);
        assert!(parallel(&(e.orientation * Vector3::x()), &Vector3::x()));
        assert!(parallel(&(e.orientation * Vector3::z()), &Vector3::z()));
        // The y-major case: the x axis is turned onto y.
        let cov = Matrix3::new(1.0, 0.0, 0.0, 0.0, 4.0, 0.0, 0.0, 0.0, 0.0);
        let e = ellipsoid(&cov, 2, K, 0.01).expect("finite");
        assert_eq!(e.size, [12.0, 6.0, 0.01]);
        assert!(parallel(&(e.orientation * Vector3::x()), &Vector3::y()));
    }

    #[test]
    fn rotated_2d_covariance_at_30_degrees() {
        let t = 30f64.to_radians();
        let rot = Matrix2::new(t.cos(), -t.sin(), t.sin(), t.cos());
        let c2 = rot * Matrix2::new(9.0, 0.0, 0.0, 1.0) * rot.transpose();
        let cov = Matrix3::new(
            c2[(0, 0)],
            c2[(0, 1)],
            0.0,
            c2[(1, 0)],
            c2[(1, 1)],
            0.0,
            0.0,
            0.0,
            0.0,
        );
        let e = ellipsoid(&cov, 2, K, 0.01).expect("finite");
        assert!((e.size[0] - 18.0).abs() < 1e-9 && (e.size[1] - 6.0).abs() < 1e-9);
        let q = e.orientation;
        assert!((q.norm() - 1.0).abs() < 1e-12);
        // A turn about z only, by 30° (or 210°: the same ellipse).
        assert!(q.i.abs() < 1e-12 && q.j.abs() < 1e-12, "{q:?}");
        let major = Vector3::new(t.cos(), t.sin(), 0.0);
        assert!(parallel(&(q * Vector3::x()), &major));
        assert!(parallel(&(q * Vector3::z()), &Vector3::z()));
        let angle = q.angle() * q.axis().map_or(1.0, |a| a.z.signum());
        let m = (angle.to_degrees() - 30.0).rem_euclid(180.0);
        assert!(m < 1e-9 || 180.0 - m < 1e-9, "angle {}", angle.to_degrees());
        let back = rebuilt(&e, 2);
        assert!((back - cov).abs().max() < 1e-9, "{back} vs {cov}");
    }

    #[test]
    fn rotated_3d_covariance_rebuilds_and_orders_the_axes() {
        let axis = nalgebra::Unit::new_normalize(Vector3::new(1.0, 2.0, 0.5));
        let rot = Rotation3::from_axis_angle(&axis, 0.7).into_inner();
        let cov = rot * Matrix3::from_diagonal(&Vector3::new(1.0, 9.0, 4.0)) * rot.transpose();
        let e = ellipsoid(&cov, 3, K, 0.01).expect("finite");
        for (s, want) in e.size.iter().zip([18.0, 12.0, 6.0]) {
            assert!((s - want).abs() < 1e-9, "{:?}", e.size);
        }
        let q = e.orientation;
        assert!((q.norm() - 1.0).abs() < 1e-12);
        assert!(q.to_rotation_matrix().matrix().determinant() > 0.999_999);
        // Major (σ² = 9) was rot's y column, then z (4), then x (1).
        assert!(parallel(&(q * Vector3::x()), &rot.column(1).into_owned()));
        assert!(parallel(&(q * Vector3::y()), &rot.column(2).into_owned()));
        assert!(parallel(&(q * Vector3::z()), &rot.column(0).into_owned()));
        let back = rebuilt(&e, 3);
        assert!((back - cov).abs().max() < 1e-9, "{back} vs {cov}");
    }

    #[test]
    fn degenerate_and_non_finite_covariances() {
        let e = ellipsoid(&Matrix3::zeros(), 3, K, 0.01).expect("finite");
        assert_eq!(e.size, [0.0, 0.0, 0.0]);
        assert!((e.orientation.norm() - 1.0).abs() < 1e-12);
        // Round-off below zero is clamped, not NaN.
        let cov = Matrix3::new(1.0, 0.0, 0.0, 0.0, -1e-18, 0.0, 0.0, 0.0, 0.0);
        let e = ellipsoid(&cov, 2, K, 0.01).expect("finite");
        assert_eq!(e.size[1], 0.0);
        let mut bad = Matrix3::identity();
        bad[(0, 1)] = f64::NAN;
        assert!(ellipsoid(&bad, 3, K, 0.01).is_none());
        assert!(ellipsoid(&bad, 2, K, 0.01).is_none());
    }

    #[test]
    fn wire_values_become_3d() {
        let v = [1.0, 2.0, 3.0, 4.0, 0.0, 0.0];
        assert_eq!(point3(&v, 2), Vector3::new(1.0, 2.0, 0.0));
        assert_eq!(point3(&v, 3), Vector3::new(1.0, 2.0, 3.0));
        let mut m = [[0.0; 6]; 6];
        m[0][0] = 1.0;
        m[2][2] = 5.0;
        assert_eq!(block3(&m, 2)[(2, 2)], 0.0);
        assert_eq!(block3(&m, 3)[(2, 2)], 5.0);
    }
}
