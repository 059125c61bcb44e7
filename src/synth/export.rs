//! Writing a take for other tools: BVH (Blender, game engines), JSON, NPY and glTF (`.glb`, a
//! skinned character, see [`super::gltf`]). Every write
//! is atomic: a failed export leaves no half-written file behind.

use std::path::{Path, PathBuf};

use std::sync::Arc;

use anyhow::{bail, Context, Result};
use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::SegmentSpan;
use crate::data::bvh::{read_bvh, write_bvh};
use crate::data::npy::{motion_from_npy, motion_to_npy};
use crate::model::spec::ModelSpec;
use crate::data::input::{check_plausible, read_bytes, read_text, MAX_MOTION_BYTES};
use crate::data::write::write_atomic;
use crate::motion::contacts::FootContacts;
use crate::motion::{local_poses, under_new_root, with_root_motion, LocalPose, Motion, RootMotion, Skeleton};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExportFormat {
    Bvh,
    Json,
    Npy,
    Glb,
}

impl ExportFormat {
    /// The format a file name asks for, by its extension.
    pub fn from_path(path: &Path) -> Result<Self> {
        match path.extension().and_then(|e| e.to_str()).map(str::to_lowercase).as_deref() {
            Some("bvh") => Ok(Self::Bvh),
            Some("json") => Ok(Self::Json),
            Some("npy") => Ok(Self::Npy),
            Some("glb") => Ok(Self::Glb),
            Some("fbx") => bail!("{}: glocal writes no FBX itself; write a .glb or .bvh and export FBX from Blender (the add-on in integrations/blender does both in one step)", path.display()),
            _ => bail!("{}: the file name must end in .bvh, .json or .npy, or .glb for a glTF character", path.display()),
        }
    }
}

#[derive(Serialize, Deserialize)]
struct JsonTake {
    fps: f32,
    meters_per_unit: f32,
    joints: Vec<String>,
    parents: Vec<i64>,
    segments: Vec<SegmentSpan>,
    /// frames x joints x [x, y, z]
    frames: Vec<Vec<[f32; 3]>>,
    /// Per foot and frame, whether the foot stands on the floor (takes from `generate`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    contacts: Option<JsonContacts>,
}

#[derive(Serialize, Deserialize)]
struct JsonContacts {
    left_foot: Vec<bool>,
    right_foot: Vec<bool>,
}

/// Writes `motion` (already cut to the range to export) to `path` in the format its
/// extension names. BVH gets the skeleton's hierarchy with rotations solved against its
/// rest pose and the take's frame time; JSON and NPY get world positions. The take is set on
/// the floor (its feet, or its seat on a floor sit, at height 0: [`Motion::floor_height`]), as animation tools expect: the models' own
/// worlds keep the dataset's origin (Human3.6M's hips at 0, its feet near -0.9 m).
pub fn export(motion: &Motion, segments: &[SegmentSpan], path: &Path) -> Result<()> {
    export_with_contacts(motion, segments, None, path)
}

/// [`export`], with the per-foot contact arrays in the JSON format where they hold one flag
/// per frame of `motion` (contacts are per frame of the model's rate: a resampled take
/// goes without them).
pub fn export_with_contacts(motion: &Motion, segments: &[SegmentSpan], contacts: Option<&FootContacts>, path: &Path) -> Result<()> {
    let contacts = contacts.filter(|c| c.left.len() == motion.frames() && c.right.len() == motion.frames());
    // Whatever went wrong upstream, no NaN, inf or null reaches a file.
    if let Some(bad) = motion.positions().iter().position(|p| !p.is_finite()) {
        bail!("{}: not written: the take has a non-finite position at frame {}", path.display(), bad / motion.joints().max(1) + 1);
    }
    let motion = &motion.translated(Vec3::new(0.0, -motion.floor_height(), 0.0));
    let bytes = match ExportFormat::from_path(path)? {
        ExportFormat::Bvh => write_bvh(motion, None).into_bytes(),
        ExportFormat::Npy => motion_to_npy(motion),
        ExportFormat::Glb => super::gltf::glb_bytes(motion)?,
        ExportFormat::Json => {
            let take = JsonTake {
                fps: motion.fps,
                meters_per_unit: motion.skeleton.meters_per_unit(),
                joints: motion.skeleton.names().to_vec(),
                parents: motion.skeleton.parents().iter().map(|p| p.map_or(-1, |p| p as i64)).collect(),
                segments: segments.to_vec(),
                frames: (0..motion.frames()).map(|t| motion.frame(t).iter().map(|p| p.to_array()).collect()).collect(),
                contacts: contacts.map(|c| JsonContacts { left_foot: c.left.clone(), right_foot: c.right.clone() }),
            };
            serde_json::to_vec(&take)?
        }
    };
    write_atomic(path, &bytes)
}

/// The segments of a take that overlap frames `[start, end)`, shifted to start at 0.
pub fn segments_in_range(segments: &[SegmentSpan], start: usize, end: usize) -> Vec<SegmentSpan> {
    segments
        .iter()
        .filter(|s| s.end_frame > start && s.start_frame < end)
        .map(|s| SegmentSpan { start_frame: s.start_frame.max(start) - start, end_frame: s.end_frame.min(end) - start, ..s.clone() })
        .collect()
}

/// Reads a take back: our JSON (with its segments), a BVH, or an NPY on a model's skeleton.
pub fn read_take(path: &Path, model_dir: Option<&Path>) -> Result<(Motion, Vec<SegmentSpan>)> {
    let name = path.display().to_string();
    match ExportFormat::from_path(path)? {
        ExportFormat::Json => {
            parse_json_take(&read_bytes(path, MAX_MOTION_BYTES)?, &name)
        }
        ExportFormat::Bvh => {
            let motion = read_bvh(&read_text(path, MAX_MOTION_BYTES)?, &name)?;
            check_plausible(&motion, &name, &motion.skeleton)?;
            Ok((motion, Vec::new()))
        }
        ExportFormat::Glb => bail!("{name}: a .glb take cannot be read back; export it as JSON or BVH too"),
        ExportFormat::Npy => {
            let dir = model_dir.with_context(|| format!("{name}: an NPY take has no skeleton; give the model folder it came from"))?;
            let spec = ModelSpec::read(dir)?;
            let motion = motion_from_npy(&read_bytes(path, MAX_MOTION_BYTES)?, &name, spec.layout.skeleton.clone(), spec.fps)?;
            check_plausible(&motion, &name, &motion.skeleton)?;
            Ok((motion, Vec::new()))
        }
    }
}

/// A JSON take's bytes as a motion, its frame rate, skeleton, frames and segments checked.
pub fn parse_json_take(bytes: &[u8], name: &str) -> Result<(Motion, Vec<SegmentSpan>)> {
    let take: JsonTake = serde_json::from_slice(bytes).map_err(|e| anyhow::anyhow!("{name}: line {}: not a take written by glocal: {e}", e.line()))?;
    if !(take.fps.is_finite() && (1.0..=1000.0).contains(&take.fps)) {
        bail!("{name}: fps is {}; a take has 1 to 1000 frames per second", take.fps);
    }
    let rest = take.frames.first().with_context(|| format!("{name} has no frames"))?;
    if let Some(bad) = take.frames.iter().position(|f| f.len() != rest.len()) {
        bail!("{name}: frame {} has {} joints, frame 1 has {}", bad + 1, take.frames[bad].len(), rest.len());
    }
    let parents = take.parents.iter().map(|&p| usize::try_from(p).ok()).collect();
    // The skeleton's rest offsets are the first frame's bones.
    let offsets = rest
        .iter()
        .zip(&take.parents)
        .map(|(p, &parent)| Vec3::from_array(*p) - usize::try_from(parent).ok().and_then(|q| rest.get(q)).map_or(Vec3::ZERO, |q| Vec3::from_array(*q)))
        .collect();
    let skeleton = Skeleton::new(take.joints, parents, offsets, take.meters_per_unit).with_context(|| format!("{name}: bad skeleton"))?;
    if rest.len() != skeleton.len() {
        bail!("{name}: frames have {} joints, the skeleton {}", rest.len(), skeleton.len());
    }
    let frames = take.frames.len();
    if let Some((k, s)) = take.segments.iter().enumerate().find(|(_, s)| s.start_frame > s.end_frame || s.end_frame > frames) {
        bail!("{name}: segment {} spans frames {}..{}, outside the take's {frames}", k + 1, s.start_frame, s.end_frame);
    }
    let positions = take.frames.iter().flatten().map(|p| Vec3::from_array(*p)).collect();
    let motion = Motion::from_positions(Arc::new(skeleton), take.fps, positions);
    check_plausible(&motion, name, &motion.skeleton)?;
    Ok((motion, take.segments))
}

/// Length unit of an export.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Units {
    /// Metres: what game engines (and Blender's scene unit) expect.
    Metres,
    Centimetres,
    /// The model's own unit (Human3.6M millimetres, Bandai centimetres).
    Native,
}

impl Units {
    /// Metres per unit of a take written in these units (`native`: the take's own).
    pub fn meters_per_unit(self, native: f32) -> f32 {
        match self {
            Units::Metres => 1.0,
            Units::Centimetres => 0.01,
            Units::Native => native,
        }
    }
}

/// What pipelines ask of an exported take besides its format.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExportOptions {
    pub units: Units,
    /// Frame rate of the file (None: the model's own).
    pub fps: Option<f32>,
    /// Put back the source skeleton's root joint the model dropped (Bandai's `joint_Root`).
    pub source_root: bool,
    /// Where the take's travel goes: the hips, nowhere (in place), or an added root bone.
    #[serde(default)]
    pub root_motion: RootMotion,
    /// A BVH whose skeleton (hierarchy, rest pose, joint names) the take is written on
    /// ([`super::own_start::take_on_rig`]); None: the model's own.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rig: Option<PathBuf>,
}

impl Default for ExportOptions {
    fn default() -> Self {
        Self { units: Units::Metres, fps: None, source_root: false, root_motion: RootMotion::Travel, rig: None }
    }
}

/// The take in `meters_per_unit` units: offsets, positions and root translations scaled.
pub fn in_units(motion: &Motion, meters_per_unit: f32) -> Result<Motion> {
    let s = &motion.skeleton;
    let k = s.meters_per_unit() / meters_per_unit;
    if !(k.is_finite() && k > 0.0) {
        bail!("cannot convert a take from {} to {meters_per_unit} metres per unit", s.meters_per_unit());
    }
    let skeleton = Arc::new(Skeleton::new(s.names().to_vec(), s.parents().to_vec(), s.offsets().iter().map(|o| *o * k).collect(), meters_per_unit)?);
    let mut out = match &motion.local_poses {
        Some(poses) => {
            let scaled = poses.iter().map(|p| LocalPose { rotations: p.rotations.clone(), translations: p.translations.iter().map(|t| *t * k).collect() }).collect();
            Motion::from_local_poses(skeleton, motion.fps, scaled)
        }
        None => Motion::from_positions(skeleton, motion.fps, motion.positions().iter().map(|p| *p * k).collect()),
    };
    out.fps = motion.fps;
    Ok(out)
}

/// The take resampled to `fps` for export, with its segment spans moved to the new frames.
pub fn resampled(motion: &Motion, segments: &[SegmentSpan], fps: f32) -> Result<(Motion, Vec<SegmentSpan>)> {
    if !(fps.is_finite() && (1.0..=1000.0).contains(&fps)) {
        bail!("export frame rate {fps}: expected 1 to 1000 fps");
    }
    let out = motion.resample(fps);
    let (n, ratio) = (out.frames(), f64::from(fps) / f64::from(motion.fps));
    let frame = |f: usize| ((f as f64 * ratio).round() as usize).min(n);
    let spans = segments.iter().map(|s| SegmentSpan { start_frame: frame(s.start_frame), end_frame: frame(s.end_frame), ..s.clone() }).collect();
    Ok((out, spans))
}

/// The take with `source`'s root joint put back above the model's root, when the model
/// dropped it (Bandai's placement handle `joint_Root`); None when the roots are the same.
/// The handle follows the hips on the ground (their projection at height 0, no rotation),
/// as in the source data; the hips keep their motion under it.
pub fn with_source_root(motion: &Motion, source: &Skeleton) -> Result<Option<Motion>> {
    // Joint 0 is a skeleton's root.
    let s = &motion.skeleton;
    let root = 0;
    if source.names()[0] == s.names()[root] {
        return Ok(None);
    }
    let skeleton = under_new_root(s, &source.names()[0])?;
    let poses = local_poses(motion)
        .iter()
        .enumerate()
        .map(|(t, p)| {
            let hips = motion.frame(t)[root];
            let handle = Vec3::new(hips.x, 0.0, hips.z);
            let mut translations = vec![handle];
            translations.extend(p.translations.iter().enumerate().map(|(j, &v)| if j == root { v - handle } else { v }));
            let mut rotations = vec![glam::Quat::IDENTITY];
            rotations.extend(p.rotations.iter().copied());
            LocalPose { rotations, translations }
        })
        .collect();
    Ok(Some(Motion::from_local_poses(skeleton, motion.fps, poses)))
}

/// The take as `options` ask, set on the floor first so units and the added root agree
/// with what [`export`] writes. `source` is the model's source skeleton (for the root).
pub fn prepare(motion: &Motion, segments: &[SegmentSpan], options: &ExportOptions, source: &Skeleton) -> Result<(Motion, Vec<SegmentSpan>)> {
    let mut m = motion.translated(Vec3::new(0.0, -motion.floor_height(), 0.0));
    let mut spans = segments.to_vec();
    if let Some(fps) = options.fps.filter(|f| (f - motion.fps).abs() > 1e-3) {
        (m, spans) = resampled(&m, &spans, fps)?;
    }
    // A root bone carries the travel the source's placement handle would.
    if options.root_motion != RootMotion::Travel {
        m = with_root_motion(&m, options.root_motion)?;
    } else if options.source_root {
        if let Some(rooted) = with_source_root(&m, source)? {
            m = rooted;
        }
    }
    let unit = options.units.meters_per_unit(m.skeleton.meters_per_unit());
    Ok((in_units(&m, unit)?, spans))
}
