//! Motion in: an animated glTF 2.0 scene read into what `timbre-ir` renders.
//!
//! [`Shot::read`] takes the bytes of a `.glb` or `.gltf` file; the bytes of every
//! external buffer come through the caller's `resource` function (the language's
//! sandboxed loader), `data:` URIs are decoded here, and nothing touches the file
//! system. A shot names every node by its glTF name and gives its world motion as
//! [`Trajectory`] objects with exact derivatives, its mesh, and whether it is a camera.
//! This crate does not read images, materials, lights or skins' joints, and knows no
//! language: `timbre-lang` turns `(motion …)` and `:object` into calls of this API.
//!
//! - **Units and axes.** Metres and seconds. glTF is Y-up and timbre Z-up: a glTF
//!   point (x, y, z) is timbre's (x, −z, y). Blender's exporter writes Blender's
//!   (x, y, z) as glTF (x, z, −y), so positions are what Blender shows.
//! - **Hierarchy.** A node's world transform is its parent's times its local one, the
//!   local one being its `matrix` or T·R·S. All nodes of the file are read, in every
//!   scene. A node driven by an animation but written with a `matrix` is animated from
//!   the matrix's decomposition (the spec forbids that case; shear is then lost).
//! - **Samplers** exactly as glTF 2.0 Appendix C: STEP holds a key's value; LINEAR is
//!   component-wise, and for rotations the spherical linear interpolation on the
//!   shortest path; CUBICSPLINE is the Hermite cubic with the file's in- and
//!   out-tangents scaled by the key interval, rotations normalised after it. Before the
//!   first key the first value, after the last the last. Normalised integer rotations
//!   are decoded as the spec says (e.g. i16: max(c/32767, −1)); every rotation key is
//!   then normalised in f64.
//! - **Exact derivatives.** Velocity and acceleration come from [`jet::Jet`]s carried
//!   through the samplers (Hermite and slerp derivatives, the derivative of the
//!   cubic-spline normalisation), T·R·S and the hierarchy's products: no finite
//!   differences. They are right-continuous at keys.
//! - **Animations.** All play together by default, or one by name
//!   ([`ShotOptions::animation`]). Two animations played together that drive the same
//!   property of one node are an error (choose one). Morph-target weights are not
//!   read (they change a shape, not where it is).
//! - **Skins.** A skinned mesh moves with its node's transform only (its root motion);
//!   joints and skin weights are not applied.
//! - **Cameras and orientation.** `forward` is the node's world transform applied to
//!   glTF's local −Z (a camera's view direction; Blender's local +Y), `up` to local +Y,
//!   both normalised and in timbre axes.
//! - **Meshes.** All triangle primitives of a node's mesh merged (strips and fans made
//!   triangles, points and lines skipped), vertices in the node's own frame in timbre
//!   axes, before the node's scale.
//! - **Bounds.** `bounds` and `max_speed` of every trajectory are proved, not sampled
//!   (see the `bounds` module): steps jump, and like `space::Path` their jumps do not
//!   count as speed.
//! - **Limits.** At most [`LIMITS`]: file and buffer bytes (`limits::MAX_FILE_BYTES`),
//!   nodes, animation keys, vertices and triangles; more is an error, not a long load.

mod bounds;
pub mod contacts;
mod error;
pub mod jet;
mod read;
pub mod sampler;
mod trajectory;

use std::collections::HashMap;
use std::sync::Arc;

use glam::{DMat3, DMat4, DQuat, DVec3};
use timbre_ir::motion::Trajectory;
use timbre_ir::StableHasher;

pub use error::MotionError;
pub use trajectory::{NodeQuantity, NodeTrajectory};

use bounds::NodeBounds;
use jet::Jet;
use read::Rest;
use sampler::Sampler;

/// The most of each thing a shot may have.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// Bytes of the file and of each buffer.
    pub file_bytes: u64,
    pub nodes: u64,
    /// Keys of all channels of the chosen animations together.
    pub keys: u64,
    /// Vertices of all meshes together.
    pub vertices: u64,
    /// Triangles of all meshes together.
    pub triangles: u64,
}

/// The limits every read checks.
pub const LIMITS: Limits = Limits {
    file_bytes: timbre_ir::limits::MAX_FILE_BYTES,
    nodes: 1 << 16,
    keys: 1 << 24,
    vertices: 1 << 24,
    triangles: 1 << 24,
};

/// How to read a shot.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ShotOptions {
    /// The animation to play; `None`: all of them together.
    pub animation: Option<String>,
}

/// A node of a [`Shot`] (its glTF node index).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct NodeIndex(pub usize);

/// A triangle mesh in its node's frame (timbre axes, metres, before the node's scale).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub vertices: Vec<DVec3>,
    /// Indices into `vertices`, counter-clockwise seen from outside (glTF's winding).
    pub triangles: Vec<[u32; 3]>,
    /// The names of its primitives' materials, in file order, each once.
    pub materials: Vec<String>,
}

/// Where a node is at one instant: its world transform in timbre axes, as a rotation
/// and a translation (a point `v` of its mesh is at `translation + rotation·(scale·v)`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    pub translation: DVec3,
    pub rotation: DQuat,
    pub scale: DVec3,
}

/// glTF axes (Y up) to timbre's (Z up): (x, y, z) → (x, −z, y).
pub fn to_timbre(v: DVec3) -> DVec3 {
    DVec3::new(v.x, -v.z, v.y)
}

/// timbre axes to glTF's: (x, y, z) → (x, z, −y).
pub fn to_gltf(v: DVec3) -> DVec3 {
    DVec3::new(v.x, v.z, -v.y)
}

#[derive(Debug)]
struct NodeData {
    name: Option<String>,
    /// From the root down to this node.
    chain: Vec<usize>,
    rest: Rest,
    /// Translation, rotation, scale.
    channels: [Option<Sampler>; 3],
    camera: bool,
    mesh: Option<Arc<Mesh>>,
    bounds: NodeBounds,
}

impl NodeData {
    fn local(&self, t: f64) -> Jet<DMat4> {
        let [translation, rotation, scale] = &self.channels;
        if translation.is_none() && rotation.is_none() && scale.is_none() {
            return Jet::constant(self.rest.matrix);
        }
        let vector = |s: &Option<Sampler>, rest: DVec3| match s {
            Some(s) => sampler::xyz(s.sample(t)),
            None => Jet::constant(rest),
        };
        let q = match rotation {
            Some(s) => s.sample(t),
            None => Jet::constant(self.rest.rotation),
        };
        jet::trs_matrix(
            vector(translation, self.rest.translation),
            q,
            vector(scale, self.rest.scale),
        )
    }
}

#[derive(Debug)]
struct ShotData {
    nodes: Vec<NodeData>,
    by_name: HashMap<String, usize>,
    animations: Vec<String>,
    duration: f64,
    hash: u64,
}

impl ShotData {
    /// Sorted times of every key of every channel that moves node `node` or an
    /// ancestor.
    fn key_times(&self, node: usize) -> Vec<f64> {
        let Some(data) = self.nodes.get(node) else {
            return Vec::new();
        };
        let mut times: Vec<f64> = data
            .chain
            .iter()
            .flat_map(|&k| self.nodes[k].channels.iter().flatten())
            .flat_map(|s| s.keys.iter().map(|k| k.time))
            .collect();
        times.sort_by(f64::total_cmp);
        times.dedup();
        times
    }

    /// The world transform of a node (glTF axes) and its derivatives.
    fn world(&self, node: usize, t: f64) -> Jet<DMat4> {
        let mut world = Jet::constant(DMat4::IDENTITY);
        for &k in &self.nodes[node].chain {
            world = jet::mat_mul(&world, &self.nodes[k].local(t));
        }
        world
    }
}

/// An animated glTF scene: its nodes' motion, meshes and cameras.
#[derive(Clone, Debug)]
pub struct Shot(Arc<ShotData>);

impl Shot {
    /// Reads a shot. `bytes`: the `.glb` or `.gltf` file; `resource(uri)` returns the
    /// bytes of an external buffer, the URI as written in the file (relative to it).
    pub fn read(
        bytes: &[u8],
        resource: &mut dyn FnMut(&str) -> Result<Vec<u8>, String>,
        options: &ShotOptions,
    ) -> Result<Shot, MotionError> {
        let gltf = read::parse(bytes)?;
        read::check_size("nodes", gltf.nodes().len() as u64, LIMITS.nodes)?;
        let buffers = read::buffers(&gltf, resource)?;
        let document = &gltf.document;
        let chosen = read::chosen_animations(document, options.animation.as_deref())?;
        let mut drives = read::drives(document, &chosen, &buffers)?;
        let chains = read::hierarchy(document)?;
        let meshes = read::meshes(document, &buffers)?;

        let mut hasher = StableHasher::new();
        hash_bytes(&mut hasher, bytes);
        for buffer in &buffers {
            hash_bytes(&mut hasher, buffer);
        }
        match &options.animation {
            Some(name) => hasher.write_str(name),
            None => hasher.write_u64(u64::MAX),
        }

        let duration = drives
            .values()
            .filter_map(|(_, s)| s.keys.last().map(|k| k.time))
            .fold(0.0, f64::max);
        let mut nodes: Vec<NodeData> = Vec::with_capacity(chains.len());
        let mut by_name = HashMap::new();
        for (node, chain) in document.nodes().zip(chains) {
            let index = node.index();
            let mut take = |p: usize| drives.remove(&(index, p)).map(|(_, s)| s);
            let channels = [take(0), take(1), take(2)];
            let animated = channels.iter().any(Option::is_some);
            let rest = read::rest(&node, animated)?;
            if let Some(name) = node.name() {
                by_name.entry(name.to_string()).or_insert(index);
            }
            nodes.push(NodeData {
                name: node.name().map(str::to_string),
                chain,
                rest,
                channels,
                camera: node.camera().is_some(),
                mesh: node.mesh().and_then(|m| meshes.get(m.index()).cloned()),
                bounds: NodeBounds::root(),
            });
        }
        // Parents before children: each chain's earlier nodes are its ancestors.
        for index in 0..nodes.len() {
            let mut bounds = NodeBounds::root();
            for &k in &nodes[index].chain {
                bounds = bounds.child(&nodes[k].rest, &nodes[k].channels);
            }
            nodes[index].bounds = bounds;
        }
        Ok(Shot(Arc::new(ShotData {
            nodes,
            by_name,
            animations: chosen.into_iter().map(|(name, _)| name).collect(),
            duration,
            hash: hasher.finish(),
        })))
    }

    /// The names of the nodes, in file order (the first of nodes sharing a name).
    pub fn node_names(&self) -> impl Iterator<Item = &str> {
        let data = &self.0;
        data.nodes.iter().enumerate().filter_map(|(k, n)| {
            let name = n.name.as_deref()?;
            (data.by_name.get(name) == Some(&k)).then_some(name)
        })
    }

    /// The node of that name (the first, if several share it).
    pub fn node(&self, name: &str) -> Option<NodeIndex> {
        self.0.by_name.get(name).map(|&k| NodeIndex(k))
    }

    /// How many nodes the file has (valid indices are below it).
    pub fn node_count(&self) -> usize {
        self.0.nodes.len()
    }

    /// The node's name, if the file gives one.
    pub fn name(&self, node: NodeIndex) -> Option<&str> {
        self.0.nodes.get(node.0)?.name.as_deref()
    }

    fn trajectory(&self, node: NodeIndex, quantity: NodeQuantity) -> Arc<dyn Trajectory> {
        Arc::new(NodeTrajectory::new(self.0.clone(), node.0, quantity))
    }

    /// World position (the node's origin), timbre axes.
    pub fn position(&self, node: NodeIndex) -> Arc<dyn Trajectory> {
        self.trajectory(node, NodeQuantity::Position)
    }

    /// The unit direction of glTF's local −Z in the world (a camera's view direction,
    /// Blender's local +Y), timbre axes.
    pub fn forward(&self, node: NodeIndex) -> Arc<dyn Trajectory> {
        self.trajectory(node, NodeQuantity::Forward)
    }

    /// The unit direction of glTF's local +Y in the world, timbre axes.
    pub fn up(&self, node: NodeIndex) -> Arc<dyn Trajectory> {
        self.trajectory(node, NodeQuantity::Up)
    }

    /// The world angular velocity ω (rad/s, timbre axes) as a moving "point": its
    /// velocity is the angular acceleration; its acceleration (the angular jerk) is not
    /// computed and reads zero. ω is that of the orthonormal frame made from the
    /// node's world x and y axes (exactly the rotation's when scales are uniform).
    pub fn angular_velocity(&self, node: NodeIndex) -> Arc<dyn Trajectory> {
        self.trajectory(node, NodeQuantity::AngularVelocity)
    }

    /// The world scale along the node's own axes, in timbre's order (local x,
    /// local −z, local y: the lengths of the world transform's columns), with exact
    /// derivatives. Lossy where the hierarchy shears (a rotated parent with unequal
    /// scales).
    pub fn scale(&self, node: NodeIndex) -> Arc<dyn Trajectory> {
        self.trajectory(node, NodeQuantity::Scale)
    }

    /// Whether the node holds a camera.
    pub fn is_camera(&self, node: NodeIndex) -> bool {
        self.0.nodes.get(node.0).is_some_and(|n| n.camera)
    }

    /// The node's mesh, if it has one with triangles.
    pub fn mesh(&self, node: NodeIndex) -> Option<&Mesh> {
        let mesh = self.0.nodes.get(node.0)?.mesh.as_deref()?;
        (!mesh.triangles.is_empty()).then_some(mesh)
    }

    /// The world box (timbre axes) of the node's mesh at `t`.
    pub fn mesh_bounds(&self, node: NodeIndex, t: f64) -> Option<(DVec3, DVec3)> {
        let mesh = self.mesh(node)?;
        let world = self.0.world(node.0, t).value;
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for &v in &mesh.vertices {
            let p = to_timbre(world.transform_point3(to_gltf(v)));
            lo = lo.min(p);
            hi = hi.max(p);
        }
        Some((lo, hi))
    }

    /// The node's world pose at `t` (timbre axes). Lossy where the hierarchy shears.
    pub fn pose(&self, node: NodeIndex, t: f64) -> Pose {
        if node.0 >= self.0.nodes.len() {
            return Pose {
                translation: DVec3::ZERO,
                rotation: DQuat::IDENTITY,
                scale: DVec3::ONE,
            };
        }
        // C·M·C⁻¹ with C the change of axes, so the matrix maps timbre-local points
        // to timbre world points.
        let axes = DMat4::from_mat3(DMat3::from_cols(
            to_timbre(DVec3::X),
            to_timbre(DVec3::Y),
            to_timbre(DVec3::Z),
        ));
        let world = axes * self.0.world(node.0, t).value * axes.transpose();
        let (scale, rotation, translation) = world.to_scale_rotation_translation();
        Pose {
            translation,
            rotation: rotation.normalize(),
            scale,
        }
    }

    /// Sorted times of every key of every channel that moves the node or an ancestor.
    pub fn key_times(&self, node: NodeIndex) -> Vec<f64> {
        self.0.key_times(node.0)
    }

    /// The last key time of the animations played (translation, rotation and scale
    /// channels), seconds; 0 for a still file.
    pub fn duration(&self) -> f64 {
        self.0.duration
    }

    /// The animations played, by name (`animation N` for one the file leaves unnamed).
    pub fn animation_names(&self) -> Vec<String> {
        self.0.animations.clone()
    }

    /// A hash of the file, its buffers and the animation chosen: stable across runs
    /// and platforms, part of every trajectory's description.
    pub fn content_hash(&self) -> u64 {
        self.0.hash
    }
}

/// The length, then the bytes eight at a time.
fn hash_bytes(hasher: &mut StableHasher, bytes: &[u8]) {
    hasher.write_u64(bytes.len() as u64);
    for chunk in bytes.chunks(8) {
        let mut word = [0u8; 8];
        word[..chunk.len()].copy_from_slice(chunk);
        hasher.write_u64(u64::from_le_bytes(word));
    }
}
