use glam::{EulerRot, Quat};
use serde::{Deserialize, Serialize};

/// The order of a joint's three rotation channels, as BVH lists them: "ZXY" means
/// R = Rz * Rx * Ry (intrinsic), the angles stored in that order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum EulerOrder {
    XYZ,
    XZY,
    YXZ,
    YZX,
    ZXY,
    ZYX,
}

impl EulerOrder {
    /// Parses the axis letters of three rotation channels in file order, e.g. `['Z','X','Y']`.
    pub fn from_axes(axes: [char; 3]) -> Option<Self> {
        Some(match axes {
            ['X', 'Y', 'Z'] => Self::XYZ,
            ['X', 'Z', 'Y'] => Self::XZY,
            ['Y', 'X', 'Z'] => Self::YXZ,
            ['Y', 'Z', 'X'] => Self::YZX,
            ['Z', 'X', 'Y'] => Self::ZXY,
            ['Z', 'Y', 'X'] => Self::ZYX,
            _ => return None,
        })
    }

    pub fn axes(self) -> [char; 3] {
        match self {
            Self::XYZ => ['X', 'Y', 'Z'],
            Self::XZY => ['X', 'Z', 'Y'],
            Self::YXZ => ['Y', 'X', 'Z'],
            Self::YZX => ['Y', 'Z', 'X'],
            Self::ZXY => ['Z', 'X', 'Y'],
            Self::ZYX => ['Z', 'Y', 'X'],
        }
    }

    fn glam(self) -> EulerRot {
        match self {
            Self::XYZ => EulerRot::XYZ,
            Self::XZY => EulerRot::XZY,
            Self::YXZ => EulerRot::YXZ,
            Self::YZX => EulerRot::YZX,
            Self::ZXY => EulerRot::ZXY,
            Self::ZYX => EulerRot::ZYX,
        }
    }
}

/// Angles in degrees, in the order's channel order.
pub fn euler_to_quat(order: EulerOrder, degrees: [f32; 3]) -> Quat {
    let [a, b, c] = degrees.map(f32::to_radians);
    Quat::from_euler(order.glam(), a, b, c)
}

/// Angles in degrees, in the order's channel order. Solved in f64 so that near-gimbal
/// poses keep their precision through a write-read round trip.
pub fn quat_to_euler(order: EulerOrder, q: Quat) -> [f32; 3] {
    let q = glam::DQuat::from_xyzw(q.x as f64, q.y as f64, q.z as f64, q.w as f64).normalize();
    let (a, b, c) = q.to_euler(order.glam());
    [a, b, c].map(|r| r.to_degrees() as f32)
}

/// The angle equal to `angle` modulo 360 degrees that is closest to `previous`, so that
/// consecutive frames never jump by a full turn.
pub fn unwrap_angle(previous: f32, angle: f32) -> f32 {
    angle - 360.0 * ((angle - previous) / 360.0).round()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn euler_round_trip_every_order() {
        for order in [EulerOrder::XYZ, EulerOrder::XZY, EulerOrder::YXZ, EulerOrder::YZX, EulerOrder::ZXY, EulerOrder::ZYX] {
            let angles = [31.0, -47.0, 112.0];
            let q = euler_to_quat(order, angles);
            let back = quat_to_euler(order, q);
            let q2 = euler_to_quat(order, back);
            assert!(q.dot(q2).abs() > 1.0 - 1e-6, "{order:?}: {angles:?} -> {back:?}");
        }
    }

    #[test]
    fn zxy_means_z_then_x_then_y() {
        let q = euler_to_quat(EulerOrder::ZXY, [30.0, 40.0, 50.0]);
        let expected = Quat::from_rotation_z(30f32.to_radians())
            * Quat::from_rotation_x(40f32.to_radians())
            * Quat::from_rotation_y(50f32.to_radians());
        assert!(q.dot(expected).abs() > 1.0 - 1e-6);
    }

    #[test]
    fn unwrap_stays_close() {
        assert!((unwrap_angle(179.0, -179.0) - 181.0).abs() < 1e-4);
        assert!((unwrap_angle(-170.0, 175.0) - -185.0).abs() < 1e-4);
        assert_eq!(unwrap_angle(10.0, 20.0), 20.0);
    }
}
