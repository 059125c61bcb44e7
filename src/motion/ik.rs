//! Analytic two-bone inverse kinematics on joint positions (hip, knee, ankle), and the hip
//! offset that lets legs reach their targets.

use glam::Vec3;

/// The fraction of a fully stretched leg the hips are kept within: a straight knee has no
/// bending direction, and one that snaps straight looks mechanical.
pub const MAX_STRETCH: f32 = 0.995;

/// Where knee and ankle go so that the ankle reaches `target` from `hip` with bones of
/// lengths `upper` (hip-knee) and `lower` (knee-ankle), bending in the plane of the old knee
/// `pole`. An unreachable target is approached as far as the leg reaches along its line.
/// Bone lengths are exact whatever the target.
pub fn two_bone(hip: Vec3, target: Vec3, pole: Vec3, upper: f32, lower: f32) -> (Vec3, Vec3) {
    let to_target = target - hip;
    let reach_min = (upper - lower).abs() * 1.0001 + 1e-6 * (upper + lower);
    let reach_max = (upper + lower) * 0.99999;
    let d = to_target.length().clamp(reach_min, reach_max.max(reach_min));
    let bend = pole - hip;
    let axis = to_target.try_normalize().or_else(|| bend.try_normalize()).unwrap_or(Vec3::NEG_Y);
    let along = (upper * upper - lower * lower + d * d) / (2.0 * d);
    let out = (upper * upper - along * along).max(0.0).sqrt();
    let side = (bend - axis * bend.dot(axis)).try_normalize().unwrap_or_else(|| axis.any_orthonormal_vector());
    let knee = hip + axis * along + side * out;
    let ankle = hip + axis * d;
    (knee, ankle)
}

/// The smallest-effort shift of the hips that brings every `(hip, target, reach)` within
/// reach: each leg pulls the hips straight towards its target by what it lacks, a few rounds
/// so two planted legs settle together. Zero when every target is already in reach.
pub fn hip_offset(legs: &[(Vec3, Vec3, f32)]) -> Vec3 {
    let mut offset = Vec3::ZERO;
    for _ in 0..8 {
        let mut moved = false;
        for &(hip, target, reach) in legs {
            let to = target - (hip + offset);
            let lack = to.length() - reach;
            if lack > 1e-6 * reach {
                offset += to.normalize() * lack;
                moved = true;
            }
        }
        if !moved {
            break;
        }
    }
    offset
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reaches_with_exact_bones() {
        let hip = Vec3::new(0.0, 1.0, 0.0);
        let pole = Vec3::new(0.0, 0.5, 0.3);
        for target in [Vec3::new(0.1, 0.2, 0.1), Vec3::new(0.0, 0.05, 0.0), Vec3::new(0.3, -0.5, 0.0)] {
            let (knee, ankle) = two_bone(hip, target, pole, 0.45, 0.45);
            assert!((knee.distance(hip) - 0.45).abs() < 1e-5);
            assert!((ankle.distance(knee) - 0.45).abs() < 1e-5);
            if target.distance(hip) < 0.9 {
                assert!(ankle.distance(target) < 1e-5);
                // The knee bends towards the pole (forward, +z).
                assert!(knee.z > 0.0);
            }
        }
    }

    #[test]
    fn hips_move_only_as_far_as_needed() {
        let legs = [(Vec3::new(0.1, 1.0, 0.0), Vec3::new(0.1, 0.0, 0.5), 0.9)];
        let offset = hip_offset(&legs);
        let (hip, target, reach) = legs[0];
        assert!(((target - (hip + offset)).length() - reach).abs() < 1e-4);
        assert_eq!(hip_offset(&[(hip, Vec3::new(0.1, 0.3, 0.0), 0.9)]), Vec3::ZERO);
    }
}
