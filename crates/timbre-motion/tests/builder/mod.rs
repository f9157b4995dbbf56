//! Writes small glTF files for the tests: JSON plus one binary buffer, packed as a
//! `.glb` or left as a `.gltf` with an external or inline buffer.

use serde_json::{json, Value};

#[derive(Default)]
pub struct Builder {
    pub bin: Vec<u8>,
    pub accessors: Vec<Value>,
    pub views: Vec<Value>,
    pub nodes: Vec<Value>,
    pub animations: Vec<Value>,
    pub meshes: Vec<Value>,
    pub cameras: Vec<Value>,
}

/// One channel: target node, path, interpolation, key times, outputs (flattened).
pub struct Channel<'a> {
    pub node: usize,
    pub path: &'a str,
    pub interpolation: &'a str,
    pub times: &'a [f32],
    pub values: &'a [f32],
}

impl Builder {
    /// Raw bytes as a buffer view and an accessor; returns the accessor.
    pub fn accessor(
        &mut self,
        bytes: &[u8],
        component_type: u32,
        kind: &str,
        count: usize,
        extra: Value,
    ) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.views
            .push(json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len()}));
        let mut accessor = json!({
            "bufferView": self.views.len() - 1,
            "componentType": component_type,
            "type": kind,
            "count": count,
        });
        if let (Value::Object(a), Value::Object(e)) = (&mut accessor, extra) {
            a.extend(e);
        }
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    /// f32 data of `kind` (SCALAR, VEC3, VEC4), with its min and max.
    pub fn floats(&mut self, data: &[f32], kind: &str) -> usize {
        let width = match kind {
            "SCALAR" => 1,
            "VEC3" => 3,
            _ => 4,
        };
        let bytes: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
        let count = data.len() / width;
        let column = |k: usize| data.iter().skip(k).step_by(width).copied();
        let min: Vec<f32> = (0..width)
            .map(|k| column(k).fold(f32::INFINITY, f32::min))
            .collect();
        let max: Vec<f32> = (0..width)
            .map(|k| column(k).fold(f32::NEG_INFINITY, f32::max))
            .collect();
        let extra = if data.iter().all(|x| x.is_finite()) {
            json!({"min": min, "max": max})
        } else {
            json!({})
        };
        self.accessor(&bytes, 5126, kind, count, extra)
    }

    pub fn node(&mut self, node: Value) -> usize {
        self.nodes.push(node);
        self.nodes.len() - 1
    }

    pub fn animation(&mut self, name: &str, channels: &[Channel]) {
        let mut samplers = Vec::new();
        let mut targets = Vec::new();
        for (k, c) in channels.iter().enumerate() {
            let input = self.floats(c.times, "SCALAR");
            let kind = if c.path == "rotation" { "VEC4" } else { "VEC3" };
            let output = self.floats(c.values, kind);
            samplers
                .push(json!({"input": input, "output": output, "interpolation": c.interpolation}));
            targets.push(json!({"sampler": k, "target": {"node": c.node, "path": c.path}}));
        }
        self.animations
            .push(json!({"name": name, "samplers": samplers, "channels": targets}));
    }

    /// A mesh of one primitive; returns the mesh index.
    pub fn mesh(&mut self, positions: &[f32], indices: Option<&[u16]>, mode: u32) -> usize {
        let position = self.floats(positions, "VEC3");
        let mut primitive = json!({"attributes": {"POSITION": position}, "mode": mode});
        if let Some(indices) = indices {
            let bytes: Vec<u8> = indices.iter().flat_map(|x| x.to_le_bytes()).collect();
            let accessor = self.accessor(&bytes, 5123, "SCALAR", indices.len(), json!({}));
            primitive["indices"] = json!(accessor);
        }
        self.meshes.push(json!({"primitives": [primitive]}));
        self.meshes.len() - 1
    }

    /// The JSON, its one buffer at `uri` (none: the GLB's binary chunk).
    pub fn json(&self, uri: Option<&str>) -> Value {
        let mut buffer = json!({"byteLength": self.bin.len()});
        if let Some(uri) = uri {
            buffer["uri"] = json!(uri);
        }
        let mut root = json!({
            "asset": {"version": "2.0"},
            "scenes": [{"nodes": []}],
            "nodes": self.nodes,
            "buffers": [buffer],
            "bufferViews": self.views,
            "accessors": self.accessors,
        });
        for (key, list) in [
            ("animations", &self.animations),
            ("meshes", &self.meshes),
            ("cameras", &self.cameras),
        ] {
            if !list.is_empty() {
                root[key] = json!(list);
            }
        }
        root
    }

    pub fn glb(&self) -> Vec<u8> {
        pack_glb(&self.json(None).to_string(), &self.bin)
    }
}

/// A GLB: header, JSON chunk padded with spaces, BIN chunk padded with zeros.
pub fn pack_glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut json = json.as_bytes().to_vec();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&0x4E4F_534Au32.to_le_bytes());
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(&0x004E_4942u32.to_le_bytes());
    out.extend_from_slice(&bin);
    out
}
