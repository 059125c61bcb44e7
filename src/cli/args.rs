//! Command-line forms of the engine's options: the engine's own types know nothing of clap.

use crate::model::spec::LossKind;
use crate::model::train::Stage;
use crate::synth::export::Units;
use crate::synth::joint_names::JointNames;
use crate::motion::RootMotion;
use crate::synth::Transition;

/// How the class changes at a segment boundary (see [`Transition`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum TransitionArg {
    Cut,
    Blend,
    Anchor,
}

impl From<TransitionArg> for Transition {
    fn from(t: TransitionArg) -> Self {
        match t {
            TransitionArg::Cut => Transition::Cut,
            TransitionArg::Blend => Transition::Blend,
            TransitionArg::Anchor => Transition::Anchor,
        }
    }
}

/// What `glocal train` makes of a model folder: one of its networks (see [`Stage`]), its
/// motion texture or its seed bank.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum StageArg {
    Glogen,
    Locgen,
    /// The in-betweener that fills the gap before a key.
    Inbetween,
    /// The motion texture of each class's training clips (no network: gathered in seconds;
    /// `crate::model::texture`).
    Texture,
    /// The seed bank: the starting windows of each class from its training clips, which a
    /// new model gets with its first stage (no network: gathered in seconds).
    Seeds,
}

impl StageArg {
    /// The network this stage trains (none for the texture and the seed bank).
    pub fn network(self) -> Option<Stage> {
        match self {
            StageArg::Glogen => Some(Stage::Glogen),
            StageArg::Locgen => Some(Stage::Locgen),
            StageArg::Inbetween => Some(Stage::Inbetween),
            StageArg::Texture | StageArg::Seeds => None,
        }
    }
}

/// The training loss's terms (see [`LossKind`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LossArg {
    /// Joint error only (L_J).
    #[value(name = "j")]
    Joint,
    /// Motion-flow error only (L_MF).
    #[value(name = "mf")]
    Flow,
    /// Both, as the paper trains (L_J + L_MF).
    #[value(name = "j+mf")]
    JointFlow,
}

impl From<LossArg> for LossKind {
    fn from(l: LossArg) -> Self {
        match l {
            LossArg::Joint => LossKind::Joint,
            LossArg::Flow => LossKind::Flow,
            LossArg::JointFlow => LossKind::JointFlow,
        }
    }
}

/// An export's length unit (see [`Units`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum UnitsArg {
    /// Metres: what game engines (and Blender's scene unit) expect.
    Metres,
    Centimetres,
    /// The model's own unit (Human3.6M millimetres, Bandai centimetres).
    Native,
}

impl From<UnitsArg> for Units {
    fn from(u: UnitsArg) -> Self {
        match u {
            UnitsArg::Metres => Units::Metres,
            UnitsArg::Centimetres => Units::Centimetres,
            UnitsArg::Native => Units::Native,
        }
    }
}

/// Where an exported take's travel goes (see [`RootMotion`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum RootMotionArg {
    /// The hips travel and turn, as generated.
    Travel,
    /// The hips' travel and turning taken out: the body moves in place.
    InPlace,
    /// An added `root` joint on the floor under the hips carries the travel and turning.
    RootBone,
}

impl From<RootMotionArg> for RootMotion {
    fn from(r: RootMotionArg) -> Self {
        match r {
            RootMotionArg::Travel => RootMotion::Travel,
            RootMotionArg::InPlace => RootMotion::InPlace,
            RootMotionArg::RootBone => RootMotion::RootBone,
        }
    }
}

/// The naming convention of an exported skeleton's joints (see [`JointNames`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum JointNamesArg {
    /// The model's (or the --retarget-to rig's) own names.
    Native,
    /// mixamorig:Hips, mixamorig:LeftUpLeg, ...
    Mixamo,
    /// The Unreal mannequin's pelvis, spine_01, thigh_l, ball_l, ...
    Unreal,
    /// Unity Mecanim's Hips, Spine, LeftUpperLeg, LeftToes, ...
    Unity,
}

impl From<JointNamesArg> for JointNames {
    fn from(n: JointNamesArg) -> Self {
        match n {
            JointNamesArg::Native => JointNames::Native,
            JointNamesArg::Mixamo => JointNames::Mixamo,
            JointNamesArg::Unreal => JointNames::Unreal,
            JointNamesArg::Unity => JointNames::Unity,
        }
    }
}
