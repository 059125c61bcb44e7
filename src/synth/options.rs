//! What a take is generated with: the timeline and its start, pace, transitions, guidance,
//! variation, the stages that run after GloGen, and the constraints (keys, a root path).
//! Plain data: projects save it as it is.

use serde::{Deserialize, Serialize};

use super::constraints::{Key, RootPath};
use super::held_frames::HeldStretch;
use super::init::InitPose;
use super::timeline::Timeline;
use crate::model::spec::ModelSpec;

/// How GloGen's class prior changes at a segment boundary.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum Transition {
    /// The paper's method: the block that starts in the new segment gets the new class.
    Cut,
    /// The class vector fades from the old class to the new one over the transition length.
    Blend,
    /// Blend, and GloGen's context is also eased towards a real pose window of the new
    /// class (from the seed bank) over the blocks of the transition, so the requested
    /// activity wins over the momentum of the previous one.
    #[default]
    Anchor,
}

/// How a key is reached (all but the default are for the ablation in docs/RESULTS.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum KeyMethod {
    /// Only the dense frames are warped onto the key, over half a second either side.
    DenseWarp,
    /// GloGen's sparse poses are warped onto the key too, over the 2 s before it (and what
    /// its block holds after it), so later blocks are conditioned on the keyed pose: of the
    /// three warps, the smoothest around keys on both models.
    SparseWarp,
    /// And the rest of the key's block is rolled out again from the keyed context: in the
    /// ablation it jerks more at its extra seam than the warp's fade does.
    RollOn,
    /// The sparse warp, and a key within the model's in-betweener's reach of the known pose
    /// before it (the last starting pose or the key before, at most 2 s) has the gap between
    /// filled by the in-betweener (`model::inbetween`) from the frames before the gap. The
    /// shipped method; on a model without an in-betweener it is the sparse warp.
    #[default]
    Inbetween,
}

/// The default length of a class change, centred on the boundary (one h36m block, two
/// Bandai blocks).
pub const DEFAULT_TRANSITION_SECONDS: f32 = 2.0;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GenerateOptions {
    pub timeline: Timeline,
    pub pace: f32,
    pub init: InitPose,
    /// Refine the frames between GloGen's poses with LocGen (off: the interpolation alone);
    /// none, as the model's LocGen says ([`crate::model::spec::LocGenSpec::by_default`]).
    pub locgen: Option<bool>,
    pub transition: Transition,
    /// Seconds over which the take changes class, centred on each boundary (a segment's own
    /// `transition` overrides it); 0 is a cut whatever `transition` says.
    pub transition_seconds: f32,
    /// Classifier-free guidance weight (1 = plain conditioning); none, the model's own
    /// ([`ModelSpec::class_strength`]).
    pub class_strength: Option<f32>,
    /// Seeds the choice of anchor windows and the small pose noise that make repeated takes
    /// differ.
    pub seed: u64,
    /// Noise added to each block's input, in normalised units, so takes with different
    /// seeds differ while staying in class (see [`GenerateOptions::varied`]).
    pub variation: f32,
    pub project_bones: bool,
    /// Re-anchor the context on a fresh seed window of the segment's class when GloGen's
    /// motion stalls, rushes or loops, and raise a stalled block's guidance (see
    /// `synth::steer`), so long segments neither freeze nor repeat.
    pub keep_alive: bool,
    /// Join each GloGen block onto the poses before it (see [`crate::model::glogen::GloGen::rollout_block`]);
    /// off, the blocks pop at every seam as in the paper.
    pub join_seams: bool,
    /// Lock planted feet in place with leg IK (see [`super::foot_lock`]), on models whose
    /// takes it suits ([`crate::model::spec::ModelSpec::foot_lock`]).
    pub foot_lock: bool,
    /// Travelling classes keep a straight course where no path is given (see
    /// [`super::course`]), on models whose walking would go round in circles
    /// ([`crate::model::spec::ModelSpec::hold_course`]).
    pub hold_course: bool,
    /// Lay the motion texture of each class's training clips over the frames between
    /// GloGen's sparse poses (see [`crate::model::texture`]), on models that ship one.
    pub texture: bool,
    /// Spread a bone's turn over the frames around it where it turns farther in one frame
    /// than the model's training clips do (see [`crate::motion::spread_snaps`]), on models
    /// that carry the limits ([`crate::model::spec::ModelSpec::bone_turn_limits`]).
    pub spread_snaps: bool,
    /// Full-body poses the take passes through (see [`super::constraints`]).
    pub keys: Vec<Key>,
    /// A path on the ground the take's locomotion follows.
    pub path: Option<RootPath>,
    pub key_method: KeyMethod,
    /// A one-activity take cut to a closed cycle for looping (see [`super::looping`]).
    #[serde(rename = "loop", skip_serializing_if = "std::ops::Not::not")]
    pub cycle: bool,
    /// Stretches of an earlier take this one keeps exactly (see [`super::held`]): the
    /// segments a reroll or an edit left alone, and locked ones.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub held: Vec<HeldStretch>,
}

impl Default for GenerateOptions {
    fn default() -> Self {
        Self {
            timeline: Timeline::default(),
            pace: 1.0,
            init: InitPose::default(),
            locgen: None,
            transition: Transition::Anchor,
            transition_seconds: DEFAULT_TRANSITION_SECONDS,
            class_strength: None,
            seed: 0,
            variation: 0.0,
            project_bones: true,
            keep_alive: true,
            join_seams: true,
            foot_lock: true,
            hold_course: true,
            texture: true,
            spread_snaps: true,
            keys: Vec::new(),
            path: None,
            key_method: KeyMethod::default(),
            cycle: false,
            held: Vec::new(),
        }
    }
}

/// Pose noise of a varied take: seed 0 is the canonical take, any other seed a variation.
pub const VARIATION: f32 = 0.05;

/// The pose noise a variation seed brings: none for seed 0 (the canonical take).
pub fn variation_for(seed: u64) -> f32 {
    if seed == 0 {
        0.0
    } else {
        VARIATION
    }
}

impl GenerateOptions {
    /// The options with variation `seed` (and the noise that goes with it).
    pub fn varied(mut self, seed: u64) -> Self {
        self.seed = seed;
        self.variation = variation_for(seed);
        self
    }

    /// The guidance a take of the model `spec` describes is made with (its classes without
    /// their own: [`Self::class_strength_of`]).
    pub fn class_strength_for(&self, spec: &ModelSpec) -> f32 {
        self.class_strength.unwrap_or(spec.class_strength)
    }

    /// Whether a take of the model `spec` describes is refined by LocGen: as the take asks,
    /// else as the model's LocGen says ([`crate::model::spec::LocGenSpec::by_default`]).
    pub fn locgen_for(&self, spec: &ModelSpec) -> bool {
        self.locgen.unwrap_or(spec.locgen.by_default)
    }

    /// The guidance the take's blocks of class `class` are made with: the take's own, else
    /// the class's ([`ModelSpec::class_strength_of`]).
    pub fn class_strength_of(&self, spec: &ModelSpec, class: usize) -> f32 {
        self.class_strength.unwrap_or_else(|| spec.class_strength_of(class))
    }
}
