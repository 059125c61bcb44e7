//! Knees stay on top of the floor. Kneeling, or sitting back on the heels on the way down to
//! the floor, h36m's network can put a knee a few centimetres through it with the foot
//! planted behind (a GloGen of h36m fine-tuned with its residual fading over blocks did in one
//! of 200 random takes: a knee 2.9 cm under for 0.2 s of a sitting down). The shin lying on
//! the floor is what holds the body there, so the whole body is lifted by the knee's depth,
//! eased in and out as a hand's lift is ([`super::hands`]); the planted foot rises by as much
//! (a few centimetres for a few frames), which a body resting on its knees does not stand on
//! anyway.

use glam::Vec3;

use super::hands::eased;
use super::{JointRoles, Side, Skeleton};

/// `positions` (frames of `skeleton`'s joints, at `fps`) lifted where a knee would be under
/// the height `floor`, so that both knees are at or above it.
pub fn keep_knees_above_floor(positions: &mut [Vec3], skeleton: &Skeleton, roles: &JointRoles, floor: f32, fps: f32) {
    let joints = skeleton.len();
    let knees = [Side::Left, Side::Right].map(|side| roles.leg(side).knee);
    let under: Vec<f32> = positions.chunks_exact(joints).map(|f| knees.iter().map(|&k| floor - f[k].y).fold(0.0, f32::max)).collect();
    if under.iter().all(|&u| u == 0.0) {
        return;
    }
    for (frame, lift) in positions.chunks_exact_mut(joints).zip(eased(&under, fps)) {
        frame.iter_mut().for_each(|p| p.y += lift);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::standard_humanoid;

    /// The standard humanoid for three seconds, its left knee 3 cm under the floor for the
    /// middle one: every knee ends on or above the floor, the body is only moved up (its
    /// shape kept), and frames well away from the kneel are as they were.
    #[test]
    fn a_knee_through_the_floor_lifts_the_body_onto_it() {
        let skeleton = standard_humanoid();
        let roles = JointRoles::new(&skeleton).unwrap();
        let knee = roles.leg(Side::Left).knee;
        let rest = skeleton.rest_positions();
        let floor = rest[knee].y + 0.03 / skeleton.meters_per_unit();
        let (fps, frames) = (30.0, 90);
        let before: Vec<Vec3> = (0..frames).flat_map(|t| rest.iter().map(move |p| if (30..60).contains(&t) { *p } else { *p + Vec3::Y })).collect();
        let mut after = before.clone();
        keep_knees_above_floor(&mut after, &skeleton, &roles, floor, fps);
        let joints = skeleton.len();
        for (t, (b, a)) in before.chunks_exact(joints).zip(after.chunks_exact(joints)).enumerate() {
            assert!(a[knee].y >= floor - 1e-4, "frame {t}: the knee {} under the floor", floor - a[knee].y);
            let lift = a[0] - b[0];
            assert!(lift.x == 0.0 && lift.z == 0.0 && lift.y >= 0.0, "frame {t}: moved by {lift}");
            assert!(b.iter().zip(a).all(|(p, q)| (*q - *p - lift).length() < 1e-5), "frame {t}: the body changed shape");
            if !(15..75).contains(&t) {
                assert_eq!(b, a, "frame {t} is far from the kneel");
            }
        }
    }
}
