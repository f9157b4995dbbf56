//! From bytes to checked data: buffers (GLB chunk, external files through the
//! caller's reader, `data:` URIs), accessors checked against their buffers before the
//! `gltf` crate reads them, samplers, hierarchy and meshes.

use std::collections::HashMap;
use std::sync::Arc;

use base64::Engine as _;
use glam::{DMat4, DQuat, DVec3, DVec4};
use gltf::accessor::{DataType, Dimensions};
use gltf::Accessor;

use crate::sampler::{Interpolation, Key, Property, Sampler};
use crate::{Mesh, MotionError, LIMITS};

/// The buffers' bytes, by buffer index.
pub type Buffers = Vec<Vec<u8>>;

pub fn parse(bytes: &[u8]) -> Result<gltf::Gltf, MotionError> {
    check_size("bytes in the file", bytes.len() as u64, LIMITS.file_bytes)?;
    let gltf =
        gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| MotionError::Parse {
            message: e.to_string(),
        })?;
    check_before_validation(&gltf.document)?;
    check_channel_targets(&gltf.document)?;
    validate(&gltf.document)?;
    Ok(gltf)
}

/// The `gltf` crate's own checks (what `Gltf::from_slice` runs), reported as one
/// error naming the first few problems.
fn validate(document: &gltf::Document) -> Result<(), MotionError> {
    use gltf::json::validation::Validate;
    let root = document.as_json();
    let mut problems = Vec::new();
    root.validate(root, gltf::json::Path::new, &mut |path, error| {
        problems.push(format!("{}: {error}", path()))
    });
    if problems.is_empty() {
        return Ok(());
    }
    let more = problems.len().saturating_sub(3);
    problems.truncate(3);
    let mut message = format!("invalid glTF: {}", problems.join("; "));
    if more > 0 {
        message.push_str(&format!(" (and {more} more)"));
    }
    Err(MotionError::Parse { message })
}

/// The `gltf` crate's validation reads a primitive's POSITION accessor without
/// checking its index (it panics on a bad one): check it first.
fn check_before_validation(document: &gltf::Document) -> Result<(), MotionError> {
    let root = document.as_json();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let position = gltf::json::validation::Checked::Valid(gltf::Semantic::Positions);
            if let Some(index) = primitive.attributes.get(&position) {
                if index.value() >= root.accessors.len() {
                    return Err(MotionError::Parse {
                        message: format!("mesh {m}, primitive {p}: no accessor {}", index.value()),
                    });
                }
            }
        }
    }
    Ok(())
}

/// The `gltf` crate's validation leaves animation channel targets unchecked, and
/// panics on reading a bad one: check them first.
fn check_channel_targets(document: &gltf::Document) -> Result<(), MotionError> {
    let root = document.as_json();
    for (a, animation) in root.animations.iter().enumerate() {
        for (c, channel) in animation.channels.iter().enumerate() {
            let target = &channel.target;
            let valid = matches!(target.path, gltf::json::validation::Checked::Valid(_))
                && target.node.value() < root.nodes.len();
            if !valid {
                return Err(MotionError::Parse {
                    message: format!("animation {a}, channel {c}: invalid target"),
                });
            }
        }
    }
    Ok(())
}

/// Every buffer's bytes, checked to be as long as the file says.
pub fn buffers(
    gltf: &gltf::Gltf,
    resource: &mut dyn FnMut(&str) -> Result<Vec<u8>, String>,
) -> Result<Buffers, MotionError> {
    let mut all = Vec::new();
    for buffer in gltf.buffers() {
        let index = buffer.index();
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf
                .blob
                .clone()
                .ok_or(MotionError::MissingBinaryChunk { buffer: index })?,
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                data_uri(uri).map_err(|message| MotionError::DataUri {
                    buffer: index,
                    message,
                })?
            }
            gltf::buffer::Source::Uri(uri) => {
                resource(uri).map_err(|message| MotionError::Resource {
                    buffer: index,
                    uri: uri.to_string(),
                    message,
                })?
            }
        };
        check_size("bytes in a buffer", data.len() as u64, LIMITS.file_bytes)?;
        if data.len() < buffer.length() {
            return Err(MotionError::ShortBuffer {
                buffer: index,
                expected: buffer.length(),
                actual: data.len(),
            });
        }
        all.push(data);
    }
    Ok(all)
}

/// `data:[<type>];base64,<data>`
fn data_uri(uri: &str) -> Result<Vec<u8>, String> {
    let (header, data) = uri
        .split_once(',')
        .ok_or_else(|| "no comma before the data".to_string())?;
    if !header.ends_with(";base64") {
        return Err("only base64 data URIs are read".into());
    }
    base64::engine::general_purpose::STANDARD
        .decode(data)
        .map_err(|e| e.to_string())
}

pub fn check_size(what: &'static str, count: u64, limit: u64) -> Result<(), MotionError> {
    if count > limit {
        return Err(MotionError::TooLarge { what, count, limit });
    }
    Ok(())
}

fn accessor_error(accessor: &Accessor, message: impl Into<String>) -> MotionError {
    MotionError::Accessor {
        accessor: accessor.index(),
        message: message.into(),
    }
}

/// Checks what the `gltf` crate's readers take for granted: the type, at least one
/// element, a stride no shorter than an element, and every byte inside its view and
/// buffer (sparse accessors are checked by the reader itself, which returns nothing
/// when out of range).
fn check_accessor(
    accessor: &Accessor,
    buffers: &Buffers,
    dimensions: Dimensions,
    types: &[DataType],
) -> Result<(), MotionError> {
    if accessor.dimensions() != dimensions || !types.contains(&accessor.data_type()) {
        return Err(accessor_error(
            accessor,
            format!(
                "is {:?} of {:?}, expected {dimensions:?} of {types:?}",
                accessor.dimensions(),
                accessor.data_type()
            ),
        ));
    }
    if accessor.count() == 0 {
        return Err(accessor_error(accessor, "has no elements"));
    }
    if accessor.sparse().is_some_and(|s| s.count() == 0) {
        return Err(accessor_error(accessor, "has an empty sparse part"));
    }
    let Some(view) = accessor.view() else {
        return if accessor.sparse().is_some() {
            Ok(())
        } else {
            Err(accessor_error(
                accessor,
                "has no buffer view (all zeros is not read)",
            ))
        };
    };
    let element = accessor.size();
    let stride = view.stride().unwrap_or(element);
    if stride < element {
        return Err(accessor_error(
            accessor,
            "has a stride shorter than an element",
        ));
    }
    let end =
        (accessor.count() as u64 - 1) * stride as u64 + element as u64 + accessor.offset() as u64;
    let view_end = view.offset() as u64 + view.length() as u64;
    let buffer_len = buffers.get(view.buffer().index()).map_or(0, |b| b.len()) as u64;
    if end > view.length() as u64 || view_end > buffer_len {
        return Err(accessor_error(
            accessor,
            "reaches past the end of its buffer",
        ));
    }
    Ok(())
}

fn missing(accessor: &Accessor) -> MotionError {
    accessor_error(accessor, "its data cannot be read")
}

/// Key times, checked: finite, strictly increasing.
fn read_times(
    accessor: &Accessor,
    buffers: &Buffers,
    animation: &str,
    sampler: usize,
) -> Result<Vec<f64>, MotionError> {
    check_accessor(accessor, buffers, Dimensions::Scalar, &[DataType::F32])?;
    check_size("animation keys", accessor.count() as u64, LIMITS.keys)?;
    let get = |b: gltf::Buffer| buffers.get(b.index()).map(|v| v.as_slice());
    let iter =
        gltf::accessor::Iter::<f32>::new(accessor.clone(), get).ok_or_else(|| missing(accessor))?;
    let times: Vec<f64> = iter.map(f64::from).collect();
    for (index, pair) in times.windows(2).enumerate() {
        if !pair[1].is_finite() || !pair[0].is_finite() {
            break;
        }
        if pair[1] <= pair[0] {
            return Err(MotionError::TimesNotIncreasing {
                animation: animation.to_string(),
                sampler,
                index: index + 1,
                previous: pair[0],
                time: pair[1],
            });
        }
    }
    if times.iter().any(|t| !t.is_finite()) {
        return Err(MotionError::NonFinite {
            what: format!("a key time of animation \"{animation}\", sampler {sampler}"),
        });
    }
    Ok(times)
}

/// A channel's outputs as vectors (w = 0) or unit quaternions (normalised integers
/// per the spec, then each key normalised in f64).
fn read_outputs(
    channel: &gltf::animation::Channel,
    property: Property,
    buffers: &Buffers,
) -> Result<Vec<DVec4>, MotionError> {
    let output = channel.sampler().output();
    let get = |b: gltf::Buffer| buffers.get(b.index()).map(|v| v.as_slice());
    let values: Vec<DVec4> = match property {
        Property::Rotation => {
            let types = [
                DataType::F32,
                DataType::I8,
                DataType::U8,
                DataType::I16,
                DataType::U16,
            ];
            check_accessor(&output, buffers, Dimensions::Vec4, &types)?;
            let reader = channel.reader(get);
            match reader.read_outputs() {
                Some(gltf::animation::util::ReadOutputs::Rotations(r)) => r
                    .into_f32()
                    .map(|q| DVec4::from(q.map(f64::from)))
                    .collect(),
                _ => return Err(missing(&output)),
            }
        }
        Property::Translation | Property::Scale => {
            check_accessor(&output, buffers, Dimensions::Vec3, &[DataType::F32])?;
            gltf::accessor::Iter::<[f32; 3]>::new(output.clone(), get)
                .ok_or_else(|| missing(&output))?
                .map(|v| DVec3::from(v.map(f64::from)).extend(0.0))
                .collect()
        }
    };
    Ok(values)
}

/// The checked sampler of one channel.
pub fn read_sampler(
    channel: &gltf::animation::Channel,
    property: Property,
    buffers: &Buffers,
    animation: &str,
) -> Result<Sampler, MotionError> {
    let sampler = channel.sampler();
    let times = read_times(&sampler.input(), buffers, animation, sampler.index())?;
    let values = read_outputs(channel, property, buffers)?;
    let interpolation = match sampler.interpolation() {
        gltf::animation::Interpolation::Step => Interpolation::Step,
        gltf::animation::Interpolation::Linear => Interpolation::Linear,
        gltf::animation::Interpolation::CubicSpline => Interpolation::CubicSpline,
    };
    let per_key = if interpolation == Interpolation::CubicSpline {
        3
    } else {
        1
    };
    if values.len() != per_key * times.len() {
        return Err(MotionError::SamplerCounts {
            animation: animation.to_string(),
            sampler: sampler.index(),
            keys: times.len(),
            outputs: values.len(),
            expected: per_key * times.len(),
        });
    }
    if values.iter().any(|v| !v.is_finite()) {
        return Err(MotionError::NonFinite {
            what: format!("a {} of animation \"{animation}\"", property.name()),
        });
    }
    let unit = |q: DVec4| {
        if property == Property::Rotation {
            q.normalize_or(DVec4::W)
        } else {
            q
        }
    };
    let keys = times
        .iter()
        .enumerate()
        .map(|(k, &time)| {
            if per_key == 3 {
                Key {
                    time,
                    in_tangent: values[3 * k],
                    value: unit(values[3 * k + 1]),
                    out_tangent: values[3 * k + 2],
                }
            } else {
                Key {
                    time,
                    in_tangent: DVec4::ZERO,
                    value: unit(values[k]),
                    out_tangent: DVec4::ZERO,
                }
            }
        })
        .collect();
    Ok(Sampler {
        property,
        interpolation,
        keys,
    })
}

/// A node's transform when no channel drives it.
#[derive(Clone, Copy, Debug)]
pub struct Rest {
    pub matrix: DMat4,
    pub translation: DVec3,
    pub rotation: DVec4,
    pub scale: DVec3,
}

/// A node's rest transform. A `matrix` is kept as written; it is decomposed into
/// T·R·S only when an animation drives the node (the spec forbids that case, and a
/// degenerate matrix then has no decomposition).
pub fn rest(node: &gltf::Node, animated: bool) -> Result<Rest, MotionError> {
    let non_finite = || MotionError::NonFinite {
        what: format!("the transform of node {}", node.index()),
    };
    let (t, r, s) = match node.transform() {
        gltf::scene::Transform::Matrix { matrix } => {
            let matrix = DMat4::from_cols_array_2d(&matrix.map(|c| c.map(f64::from)));
            if !matrix.is_finite() {
                return Err(non_finite());
            }
            if !animated {
                return Ok(Rest {
                    matrix,
                    translation: DVec3::ZERO,
                    rotation: DVec4::W,
                    scale: DVec3::ONE,
                });
            }
            node.transform().decomposed()
        }
        gltf::scene::Transform::Decomposed {
            translation,
            rotation,
            scale,
        } => (translation, rotation, scale),
    };
    let translation = DVec3::from(t.map(f64::from));
    let rotation = DVec4::from(r.map(f64::from));
    let scale = DVec3::from(s.map(f64::from));
    if !(translation.is_finite() && rotation.is_finite() && scale.is_finite()) {
        return Err(non_finite());
    }
    let rotation = rotation.normalize_or(DVec4::W);
    // Rebuilt in f64 from its parts, so that a still node and an animated one agree.
    let q = DQuat::from_vec4(rotation);
    Ok(Rest {
        matrix: DMat4::from_scale_rotation_translation(scale, q, translation),
        translation,
        rotation,
        scale,
    })
}

/// Parents by node index, and each node's chain from its root down to itself.
pub fn hierarchy(document: &gltf::Document) -> Result<Vec<Vec<usize>>, MotionError> {
    let count = document.nodes().len();
    let mut parent: Vec<Option<usize>> = vec![None; count];
    for node in document.nodes() {
        for child in node.children() {
            if parent[child.index()].is_some() {
                return Err(MotionError::Hierarchy {
                    node: child.index(),
                    message: "it has two parents".into(),
                });
            }
            parent[child.index()] = Some(node.index());
        }
    }
    let mut chains = Vec::with_capacity(count);
    for index in 0..count {
        let mut chain = vec![index];
        let mut at = index;
        while let Some(p) = parent[at] {
            if chain.len() > count {
                return Err(MotionError::Hierarchy {
                    node: index,
                    message: "it is its own ancestor".into(),
                });
            }
            chain.push(p);
            at = p;
        }
        chain.reverse();
        chains.push(chain);
    }
    Ok(chains)
}

/// Every mesh, its primitives' triangles merged, positions in timbre axes.
pub fn meshes(document: &gltf::Document, buffers: &Buffers) -> Result<Vec<Arc<Mesh>>, MotionError> {
    let mut vertices_total = 0u64;
    let mut triangles_total = 0u64;
    let mut all = Vec::new();
    for mesh in document.meshes() {
        let mut out = Mesh::default();
        for primitive in mesh.primitives() {
            let mode = primitive.mode();
            use gltf::mesh::Mode;
            if !matches!(
                mode,
                Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
            ) {
                continue;
            }
            let Some(positions) = primitive.get(&gltf::Semantic::Positions) else {
                continue;
            };
            if let Some(name) = primitive.material().name() {
                if !out.materials.iter().any(|m| m == name) {
                    out.materials.push(name.to_string());
                }
            }
            check_accessor(&positions, buffers, Dimensions::Vec3, &[DataType::F32])?;
            vertices_total += positions.count() as u64;
            check_size("vertices", vertices_total, LIMITS.vertices)?;
            let get = |b: gltf::Buffer| buffers.get(b.index()).map(|v| v.as_slice());
            let base = out.vertices.len() as u32;
            let points = gltf::accessor::Iter::<[f32; 3]>::new(positions.clone(), get)
                .ok_or_else(|| missing(&positions))?;
            for p in points {
                let p = DVec3::from(p.map(f64::from));
                if !p.is_finite() {
                    return Err(MotionError::NonFinite {
                        what: format!("a vertex of mesh {}", mesh.index()),
                    });
                }
                out.vertices.push(crate::to_timbre(p));
            }
            let indices: Vec<u32> = match primitive.indices() {
                Some(accessor) => {
                    let types = [DataType::U8, DataType::U16, DataType::U32];
                    check_accessor(&accessor, buffers, Dimensions::Scalar, &types)?;
                    check_size(
                        "vertex indices",
                        accessor.count() as u64,
                        3 * LIMITS.triangles,
                    )?;
                    let reader = primitive.reader(get);
                    let read = reader.read_indices().ok_or_else(|| missing(&accessor))?;
                    let indices: Vec<u32> = read.into_u32().collect();
                    if indices.iter().any(|&i| i as usize >= positions.count()) {
                        return Err(accessor_error(
                            &accessor,
                            "has an index past the last vertex",
                        ));
                    }
                    indices
                }
                None => (0..positions.count() as u32).collect(),
            };
            let triangles = triangles(mode, &indices);
            triangles_total += triangles.len() as u64;
            check_size("triangles", triangles_total, LIMITS.triangles)?;
            out.triangles
                .extend(triangles.into_iter().map(|t| t.map(|i| i + base)));
        }
        all.push(Arc::new(out));
    }
    Ok(all)
}

/// Triangles of a primitive (glTF 2.0 §3.7.2.1): lists by threes; strips
/// {i, i+1+i%2, i+2−i%2}; fans {i+1, i+2, 0}.
fn triangles(mode: gltf::mesh::Mode, indices: &[u32]) -> Vec<[u32; 3]> {
    use gltf::mesh::Mode;
    let n = indices.len();
    match mode {
        Mode::TriangleStrip => (0..n.saturating_sub(2))
            .map(|i| [indices[i], indices[i + 1 + i % 2], indices[i + 2 - i % 2]])
            .collect(),
        Mode::TriangleFan => (0..n.saturating_sub(2))
            .map(|i| [indices[i + 1], indices[i + 2], indices[0]])
            .collect(),
        _ => indices
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect(),
    }
}

/// The animations to play: all, or the one named.
pub fn chosen_animations<'a>(
    document: &'a gltf::Document,
    wanted: Option<&str>,
) -> Result<Vec<(String, gltf::Animation<'a>)>, MotionError> {
    let all: Vec<(String, gltf::Animation)> = document
        .animations()
        .map(|a| (animation_name(&a), a))
        .collect();
    match wanted {
        None => Ok(all),
        Some(name) => {
            let available: Vec<String> = all.iter().map(|(n, _)| n.clone()).collect();
            let chosen: Vec<_> = all.into_iter().filter(|(n, _)| n == name).collect();
            if chosen.is_empty() {
                return Err(MotionError::UnknownAnimation {
                    name: name.to_string(),
                    available,
                });
            }
            Ok(chosen)
        }
    }
}

/// An animation's name, or `animation N` when the file gives none.
pub fn animation_name(animation: &gltf::Animation) -> String {
    animation
        .name()
        .map(str::to_string)
        .unwrap_or_else(|| format!("animation {}", animation.index()))
}

/// The samplers of the chosen animations by (node, property), and the animation each
/// came from; two animations driving the same property of one node is an error.
pub type Drives = HashMap<(usize, usize), (String, Sampler)>;

pub fn drives(
    document: &gltf::Document,
    chosen: &[(String, gltf::Animation)],
    buffers: &Buffers,
) -> Result<Drives, MotionError> {
    let mut drives: Drives = HashMap::new();
    let mut keys = 0u64;
    for (name, animation) in chosen {
        for channel in animation.channels() {
            use gltf::animation::Property as P;
            let property = match channel.target().property() {
                P::Translation => Property::Translation,
                P::Rotation => Property::Rotation,
                P::Scale => Property::Scale,
                // Morph target weights change a mesh's shape, not where it is.
                P::MorphTargetWeights => continue,
            };
            keys += channel.sampler().input().count() as u64;
            check_size("animation keys", keys, LIMITS.keys)?;
            let node = channel.target().node().index();
            let sampler = read_sampler(&channel, property, buffers, name)?;
            let slot = (node, property as usize);
            if let Some((first, _)) = drives.get(&slot) {
                if first != name {
                    let node_name = document
                        .nodes()
                        .nth(node)
                        .and_then(|n| n.name().map(str::to_string))
                        .unwrap_or_else(|| format!("#{node}"));
                    return Err(MotionError::ConflictingChannels {
                        node: node_name,
                        property: property.name(),
                        first: first.clone(),
                        second: name.clone(),
                    });
                }
            }
            // Within one animation the last channel for a property wins.
            drives.insert(slot, (name.clone(), sampler));
        }
    }
    Ok(drives)
}
