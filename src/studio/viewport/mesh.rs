//! The two unit meshes every solid is instanced from: an open cylinder along +y (radius 1,
//! height 0..1; the joint spheres cover its ends) and a once-subdivided icosphere (radius 1).

use std::collections::HashMap;

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct MeshVertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
}

/// Vertices and triangle indices of one mesh.
pub struct Mesh {
    pub vertices: Vec<MeshVertex>,
    pub indices: Vec<u16>,
}

/// Open cylinder with `sides` faces around +y, from y = 0 to y = 1, radius 1.
pub fn cylinder(sides: u16) -> Mesh {
    let mut vertices = Vec::with_capacity(2 * sides as usize);
    for i in 0..sides {
        let a = i as f32 / sides as f32 * std::f32::consts::TAU;
        let (s, c) = a.sin_cos();
        for y in [0.0, 1.0] {
            vertices.push(MeshVertex { position: [c, y, s], normal: [c, 0.0, s] });
        }
    }
    let mut indices = Vec::with_capacity(6 * sides as usize);
    for i in 0..sides {
        let j = (i + 1) % sides;
        let (b0, t0, b1, t1) = (2 * i, 2 * i + 1, 2 * j, 2 * j + 1);
        // Counter-clockwise seen from outside.
        indices.extend_from_slice(&[b0, t0, b1, b1, t0, t1]);
    }
    Mesh { vertices, indices }
}

/// Icosphere of radius 1 after `subdivisions` rounds of splitting each triangle in four.
pub fn icosphere(subdivisions: u32) -> Mesh {
    let t = (1.0 + 5.0f32.sqrt()) / 2.0;
    let mut points: Vec<Vec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .into_iter()
    .map(|p| Vec3::from(p).normalize())
    .collect();
    let mut faces: Vec<[u16; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoints: HashMap<(u16, u16), u16> = HashMap::new();
        let mut midpoint = |a: u16, b: u16, points: &mut Vec<Vec3>| -> u16 {
            let key = (a.min(b), a.max(b));
            *midpoints.entry(key).or_insert_with(|| {
                points.push(((points[a as usize] + points[b as usize]) * 0.5).normalize());
                (points.len() - 1) as u16
            })
        };
        let mut next = Vec::with_capacity(faces.len() * 4);
        for [a, b, c] in faces {
            let ab = midpoint(a, b, &mut points);
            let bc = midpoint(b, c, &mut points);
            let ca = midpoint(c, a, &mut points);
            next.extend_from_slice(&[[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        faces = next;
    }
    let vertices = points.iter().map(|p| MeshVertex { position: p.to_array(), normal: p.to_array() }).collect();
    Mesh { vertices, indices: faces.into_iter().flatten().collect() }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every triangle faces outwards (its normal agrees with its centroid's direction).
    fn outward(mesh: &Mesh, centre_of: impl Fn(Vec3) -> Vec3) {
        for tri in mesh.indices.chunks(3) {
            let [a, b, c] = [0, 1, 2].map(|k| Vec3::from(mesh.vertices[tri[k] as usize].position));
            let n = (b - a).cross(c - a);
            let centroid = (a + b + c) / 3.0;
            assert!(n.dot(centroid - centre_of(centroid)) > 0.0, "inward triangle {tri:?}");
        }
    }

    #[test]
    fn meshes_are_closed_and_outward() {
        let sphere = icosphere(1);
        assert_eq!(sphere.vertices.len(), 42);
        assert_eq!(sphere.indices.len(), 80 * 3);
        outward(&sphere, |_| Vec3::ZERO);
        let cyl = cylinder(12);
        assert_eq!(cyl.indices.len(), 12 * 6);
        outward(&cyl, |p| Vec3::new(0.0, p.y, 0.0));
    }
}
