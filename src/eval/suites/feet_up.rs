//! Whether a take's feet stand on its floor, as exported: the measure the first takes and the
//! random takes hold to issue 39's first-take lines.

use anyhow::Result;

use crate::motion::contacts::{lowest_foot_heights, runs, FootContacts};
use crate::motion::{JointRoles, Motion, Side};

/// A lowest foot joint this far above the floor (metres) is up.
pub(super) const FEET_UP_M: f32 = 0.05;

/// Feet up (fraction of frames), the longest float (s) and the locked contacts' frames off the
/// floor (fraction), over the export's floor; the frames before `from` (a file start's own
/// motion) are not judged, but counted among the take's frames.
pub(super) fn feet_on_the_floor(m: &Motion, contacts: &FootContacts, from: usize) -> Result<(f64, f32, f64)> {
    let roles = JointRoles::new(&m.skeleton)?;
    let unit = m.skeleton.meters_per_unit();
    let floor = m.floor_height();
    let up = |h: f32| (h - floor) * unit > FEET_UP_M;
    let floating: Vec<bool> = lowest_foot_heights(m, &roles).into_iter().enumerate().map(|(t, h)| t >= from && up(h)).collect();
    let feet_up = floating.iter().filter(|&&f| f).count() as f64 / floating.len().max(1) as f64;
    let longest = runs(&floating).iter().map(|r| r.len()).max().unwrap_or(0) as f32 / m.fps;
    let (mut planted, mut off) = (0usize, 0usize);
    for side in Side::BOTH {
        let foot = roles.leg(side).foot_joints(&m.skeleton);
        for (t, _) in contacts.side(side).iter().enumerate().skip(from).filter(|(_, &c)| c) {
            planted += 1;
            off += usize::from(up(foot.iter().map(|&j| m.frame(t)[j].y).fold(f32::INFINITY, f32::min)));
        }
    }
    Ok((feet_up, longest, off as f64 / planted.max(1) as f64))
}
