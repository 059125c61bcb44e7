//! glTF 2.0 binary export (`.glb`): the take as a skinned character any viewer or engine shows.
//!
//! - Nodes: one per joint, in skeleton order, at its rest offset (metres); the rest pose is
//!   the bind pose, so every inverse bind matrix is a translation.
//! - Mesh: a mannequin of capsules, one per bone longer than 1 cm, from the parent joint to
//!   the joint, each bound wholly to the parent (rigid limbs need no weight painting), plus a
//!   trunk, pelvis and head when the skeleton is a humanoid; one blue material.
//! - Animation "take": per joint a rotation channel (the local rotations BVH export writes,
//!   kept on one hemisphere from frame to frame so interpolation takes the short way), and a
//!   translation channel for the root and any joint that leaves its rest offset; keyframe k
//!   at k / fps seconds, linear interpolation.
//! - Units: metres, y up, as glTF requires; the caller sets the take on the floor.
//!
//! The document is built with `gltf-json` and packed with `gltf`'s GLB writer.

use std::borrow::Cow;
use std::collections::BTreeMap;

use anyhow::{bail, Result};
use glam::{Mat4, Quat, Vec3};
use gltf_json as json;
use json::validation::Checked::Valid;
use json::validation::USize64;

use crate::data::joint_map::key_joints;
use crate::motion::{solve_local_poses, Key, KeyJoints, LocalPose, Motion, Skeleton};

/// Capsule radius as a fraction of its bone's length, and its bounds in metres.
const LIMB_THICKNESS: f32 = 0.16;
const LIMB_RADIUS: (f32, f32) = (0.02, 0.06);
const HEAD_RADIUS: f32 = 0.09;
const TRUNK_RADIUS: f32 = 0.1;
const PELVIS_RADIUS: f32 = 0.07;
/// Bones shorter than this (metres) get no capsule: duplicate joints, collapsed end sites.
const MIN_BONE: f32 = 0.01;
/// Segments around a capsule and rings per half-sphere.
const SEGMENTS: usize = 10;
const CAP_RINGS: usize = 3;

/// The take as a binary glTF file.
pub fn glb_bytes(motion: &Motion) -> Result<Vec<u8>> {
    if motion.frames() == 0 {
        bail!("the take has no frames to export");
    }
    let poses = local_poses(motion);
    let skeleton = &*motion.skeleton;
    let scale = skeleton.meters_per_unit();
    let mut doc = Document::default();
    let joints = doc.joint_nodes(skeleton, scale);
    let skin = doc.skin(skeleton, scale, &joints);
    let mesh = doc.mannequin(skeleton, scale);
    let mesh_node = doc.root.push(json::Node { name: Some("Mannequin".into()), mesh: Some(mesh), skin: Some(skin), ..Default::default() });
    doc.animation(motion, &poses, scale, &joints);
    let mut scene_nodes: Vec<_> = (0..skeleton.len()).filter(|&j| skeleton.parents()[j].is_none()).map(|j| joints[j]).collect();
    scene_nodes.push(mesh_node);
    let scene = doc.root.push(json::Scene { extensions: None, extras: Default::default(), name: Some("Take".into()), nodes: scene_nodes });
    doc.root.scene = Some(scene);
    doc.finish()
}

/// The motion's own local rotations when they fit its skeleton, else solved from positions
/// against the rest pose (as BVH export does).
fn local_poses(motion: &Motion) -> Vec<LocalPose> {
    let n = motion.joints();
    match &motion.local_poses {
        Some(p) if p.len() == motion.frames() && p.iter().all(|q| q.rotations.len() == n && q.translations.len() == n) => p.clone(),
        _ => solve_local_poses(&motion.skeleton, motion.positions()),
    }
}

#[derive(Default)]
struct Document {
    root: json::Root,
    bin: Vec<u8>,
}

impl Document {
    /// Appends `bytes` (4-byte aligned) as a buffer view.
    fn view(&mut self, bytes: &[u8], target: Option<json::buffer::Target>) -> json::Index<json::buffer::View> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.root.push(json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            extensions: None,
            extras: Default::default(),
            name: None,
            target: target.map(Valid),
        })
    }

    /// A float accessor of `width`-component elements (`kind` VEC3, VEC4, MAT4, SCALAR);
    /// `bounds` adds min and max, which positions and animation times must have.
    fn floats(&mut self, values: &[f32], width: usize, kind: json::accessor::Type, target: Option<json::buffer::Target>, bounds: bool) -> json::Index<json::Accessor> {
        let view = self.view(bytemuck::cast_slice(values), target);
        let (min, max) = if bounds {
            let mut min = vec![f32::INFINITY; width];
            let mut max = vec![f32::NEG_INFINITY; width];
            for chunk in values.chunks_exact(width) {
                for (k, v) in chunk.iter().enumerate() {
                    min[k] = min[k].min(*v);
                    max[k] = max[k].max(*v);
                }
            }
            (Some(json::Value::from(min)), Some(json::Value::from(max)))
        } else {
            (None, None)
        };
        self.accessor(view, values.len() / width, json::accessor::ComponentType::F32, kind, min, max)
    }

    fn accessor(
        &mut self,
        view: json::Index<json::buffer::View>,
        count: usize,
        component: json::accessor::ComponentType,
        kind: json::accessor::Type,
        min: Option<json::Value>,
        max: Option<json::Value>,
    ) -> json::Index<json::Accessor> {
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(count),
            component_type: Valid(json::accessor::GenericComponentType(component)),
            extensions: None,
            extras: Default::default(),
            type_: Valid(kind),
            min,
            max,
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    /// One node per joint at its rest offset, children linked.
    fn joint_nodes(&mut self, skeleton: &Skeleton, scale: f32) -> Vec<json::Index<json::Node>> {
        let first = self.root.nodes.len() as u32;
        (0..skeleton.len())
            .map(|j| {
                let children: Vec<_> = skeleton.children(j).map(|c| json::Index::new(first + c as u32)).collect();
                self.root.push(json::Node {
                    name: Some(skeleton.names()[j].clone()),
                    translation: Some((skeleton.offsets()[j] * scale).to_array()),
                    children: (!children.is_empty()).then_some(children),
                    ..Default::default()
                })
            })
            .collect()
    }

    fn skin(&mut self, skeleton: &Skeleton, scale: f32, joints: &[json::Index<json::Node>]) -> json::Index<json::Skin> {
        let inverse_bind: Vec<f32> =
            skeleton.rest_positions().iter().flat_map(|p| Mat4::from_translation(-*p * scale).to_cols_array()).collect();
        let matrices = self.floats(&inverse_bind, 16, json::accessor::Type::Mat4, None, false);
        let root = (0..skeleton.len()).find(|&j| skeleton.parents()[j].is_none()).map(|j| joints[j]);
        self.root.push(json::Skin {
            extensions: None,
            extras: Default::default(),
            inverse_bind_matrices: Some(matrices),
            joints: joints.to_vec(),
            name: Some("Skeleton".into()),
            skeleton: root,
        })
    }

    /// Capsule limbs in the bind pose, each bound to the joint whose rotation moves it.
    fn mannequin(&mut self, skeleton: &Skeleton, scale: f32) -> json::Index<json::Mesh> {
        let rest: Vec<Vec3> = skeleton.rest_positions().iter().map(|p| *p * scale).collect();
        // A humanoid (most skeletons) gets a trunk, a pelvis and a head; any other skeleton
        // plain limbs.
        let keys = key_joints(skeleton, None, "").ok();
        let trunk: Vec<usize> = keys.as_ref().map_or(Vec::new(), |k| trunk_joints(skeleton, k));
        let hips = keys.as_ref().and_then(|k| k.get(Key::Hips));
        let mut mesh = CapsuleMesh::default();
        for j in 0..skeleton.len() {
            if let Some(p) = skeleton.parents()[j] {
                let length = rest[j].distance(rest[p]);
                if length >= MIN_BONE {
                    let radius = if trunk.contains(&j) {
                        TRUNK_RADIUS
                    } else if Some(p) == hips {
                        PELVIS_RADIUS
                    } else {
                        (LIMB_THICKNESS * length).clamp(LIMB_RADIUS.0, LIMB_RADIUS.1)
                    };
                    mesh.capsule(rest[p], rest[j], radius, p);
                }
            }
        }
        // The head: a ball continuing the neck above the head joint.
        if let Some(keys) = &keys {
            if let (Some(head), Some(neck)) = (keys.get(Key::Head), keys.get(Key::Neck).or(keys.get(Key::Chest))) {
                let up = (rest[head] - rest[neck]).normalize_or_zero();
                mesh.capsule(rest[head] + up * HEAD_RADIUS, rest[head] + up * 1.4 * HEAD_RADIUS, HEAD_RADIUS, head);
            }
        }
        let positions = self.floats(&mesh.positions, 3, json::accessor::Type::Vec3, Some(json::buffer::Target::ArrayBuffer), true);
        let normals = self.floats(&mesh.normals, 3, json::accessor::Type::Vec3, Some(json::buffer::Target::ArrayBuffer), false);
        let weights = self.floats(&mesh.weights, 4, json::accessor::Type::Vec4, Some(json::buffer::Target::ArrayBuffer), false);
        let view = self.view(bytemuck::cast_slice(&mesh.joints), Some(json::buffer::Target::ArrayBuffer));
        let joints = self.accessor(view, mesh.joints.len() / 4, json::accessor::ComponentType::U16, json::accessor::Type::Vec4, None, None);
        let view = self.view(bytemuck::cast_slice(&mesh.indices), Some(json::buffer::Target::ElementArrayBuffer));
        let indices = self.accessor(view, mesh.indices.len(), json::accessor::ComponentType::U32, json::accessor::Type::Scalar, None, None);
        let material = self.root.push(json::Material {
            name: Some("Mannequin".into()),
            pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                base_color_factor: json::material::PbrBaseColorFactor([0.22, 0.42, 0.72, 1.0]),
                metallic_factor: json::material::StrengthFactor(0.0),
                roughness_factor: json::material::StrengthFactor(0.7),
                ..Default::default()
            },
            ..Default::default()
        });
        let attributes = BTreeMap::from([
            (Valid(json::mesh::Semantic::Positions), positions),
            (Valid(json::mesh::Semantic::Normals), normals),
            (Valid(json::mesh::Semantic::Joints(0)), joints),
            (Valid(json::mesh::Semantic::Weights(0)), weights),
        ]);
        self.root.push(json::Mesh {
            extensions: None,
            extras: Default::default(),
            name: Some("Mannequin".into()),
            primitives: vec![json::mesh::Primitive {
                attributes,
                extensions: None,
                extras: Default::default(),
                indices: Some(indices),
                material: Some(material),
                mode: Valid(json::mesh::Mode::Triangles),
                targets: None,
            }],
            weights: None,
        })
    }

    fn animation(&mut self, motion: &Motion, poses: &[LocalPose], scale: f32, joints: &[json::Index<json::Node>]) {
        let skeleton = &*motion.skeleton;
        let times: Vec<f32> = (0..poses.len()).map(|t| t as f32 / motion.fps).collect();
        let input = self.floats(&times, 1, json::accessor::Type::Scalar, None, true);
        let mut samplers = Vec::new();
        let mut channels = Vec::new();
        let mut channel = |doc: &mut Document, node: json::Index<json::Node>, path: json::animation::Property, values: &[f32], width: usize| {
            let kind = if width == 4 { json::accessor::Type::Vec4 } else { json::accessor::Type::Vec3 };
            let output = doc.floats(values, width, kind, None, false);
            samplers.push(json::animation::Sampler {
                extensions: None,
                extras: Default::default(),
                input,
                interpolation: Valid(json::animation::Interpolation::Linear),
                output,
            });
            channels.push(json::animation::Channel {
                sampler: json::Index::new(samplers.len() as u32 - 1),
                target: json::animation::Target { extensions: None, extras: Default::default(), node, path: Valid(path) },
                extensions: None,
                extras: Default::default(),
            });
        };
        for j in 0..skeleton.len() {
            let mut previous = Quat::IDENTITY;
            let rotations: Vec<f32> = poses
                .iter()
                .flat_map(|p| {
                    let q = p.rotations[j].normalize();
                    let q = if q.dot(previous) < 0.0 { -q } else { q };
                    previous = q;
                    q.to_array()
                })
                .collect();
            channel(self, joints[j], json::animation::Property::Rotation, &rotations, 4);
            let offset = skeleton.offsets()[j];
            let moves = poses.iter().any(|p| (p.translations[j] - offset).abs().max_element() > 1e-5 * (1.0 + offset.length()));
            if skeleton.parents()[j].is_none() || moves {
                let translations: Vec<f32> = poses.iter().flat_map(|p| (p.translations[j] * scale).to_array()).collect();
                channel(self, joints[j], json::animation::Property::Translation, &translations, 3);
            }
        }
        self.root.push(json::Animation { extensions: None, extras: Default::default(), channels, name: Some("take".into()), samplers });
    }

    fn finish(mut self) -> Result<Vec<u8>> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.root.push(json::Buffer { byte_length: USize64::from(self.bin.len()), extensions: None, extras: Default::default(), name: None, uri: None });
        self.root.asset.generator = Some(format!("glocal {}", env!("CARGO_PKG_VERSION")));
        let text = json::serialize::to_vec(&self.root)?;
        let glb = gltf::binary::Glb {
            header: gltf::binary::Header { magic: *b"glTF", version: 2, length: 0 },
            json: Cow::Owned(text),
            bin: Some(Cow::Owned(self.bin)),
        };
        Ok(glb.to_vec()?)
    }
}

/// The joints on the way up from the chest to the hips (not the hips): their bones are the
/// trunk.
fn trunk_joints(skeleton: &Skeleton, keys: &KeyJoints) -> Vec<usize> {
    let (Some(hips), Some(chest)) = (keys.get(Key::Hips), keys.get(Key::Chest)) else { return Vec::new() };
    let mut out = Vec::new();
    let mut j = chest;
    while j != hips {
        out.push(j);
        match skeleton.parents()[j] {
            Some(p) => j = p,
            None => return Vec::new(),
        }
    }
    out
}

/// Capsule triangles with per-vertex joint bindings (one joint, full weight).
#[derive(Default)]
struct CapsuleMesh {
    positions: Vec<f32>,
    normals: Vec<f32>,
    joints: Vec<u16>,
    weights: Vec<f32>,
    indices: Vec<u32>,
}

impl CapsuleMesh {
    /// A capsule around the segment `a`-`b`: a pole, rings of two half-spheres, a pole.
    fn capsule(&mut self, a: Vec3, b: Vec3, radius: f32, joint: usize) {
        let axis = (b - a).normalize_or_zero();
        let turn = if axis == Vec3::ZERO { Quat::IDENTITY } else { Quat::from_rotation_arc(Vec3::Z, axis) };
        let first = (self.positions.len() / 3) as u32;
        let mut vertex = |centre: Vec3, normal: Vec3| {
            let n = turn * normal;
            self.positions.extend_from_slice(&(centre + n * radius).to_array());
            self.normals.extend_from_slice(&n.to_array());
            self.joints.extend_from_slice(&[joint as u16, 0, 0, 0]);
            self.weights.extend_from_slice(&[1.0, 0.0, 0.0, 0.0]);
        };
        vertex(a, Vec3::NEG_Z);
        let quarter = std::f32::consts::FRAC_PI_2;
        // Latitudes from just above the bottom pole to just below the top one.
        let latitudes: Vec<(f32, Vec3)> = (1..=CAP_RINGS)
            .map(|k| (-quarter + quarter * k as f32 / CAP_RINGS as f32, a))
            .chain((0..CAP_RINGS).map(|k| (quarter * k as f32 / CAP_RINGS as f32, b)))
            .collect();
        for &(lat, centre) in &latitudes {
            for s in 0..SEGMENTS {
                let lon = std::f32::consts::TAU * s as f32 / SEGMENTS as f32;
                vertex(centre, Vec3::new(lat.cos() * lon.cos(), lat.cos() * lon.sin(), lat.sin()));
            }
        }
        vertex(b, Vec3::Z);
        let rings = latitudes.len() as u32;
        let seg = SEGMENTS as u32;
        let at = |ring: u32, s: u32| first + 1 + ring * seg + s % seg;
        let top = first + 1 + rings * seg;
        for s in 0..seg {
            self.indices.extend_from_slice(&[first, at(0, s + 1), at(0, s)]);
            for r in 0..rings - 1 {
                let (p, q, u, v) = (at(r, s), at(r, s + 1), at(r + 1, s + 1), at(r + 1, s));
                self.indices.extend_from_slice(&[p, q, u, p, u, v]);
            }
            self.indices.extend_from_slice(&[at(rings - 1, s), at(rings - 1, s + 1), top]);
        }
    }
}
