//! What can be wrong with a glTF file, with what the language needs to say it at the
//! form: a message ([`std::fmt::Display`]), a code and a help line ([`MotionError::diag`]).

use timbre_diag::{Diag, Span};

/// Why a glTF file could not be read.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum MotionError {
    /// Not glTF, truncated, or invalid JSON or structure (the `gltf` crate's words).
    #[error("not a readable glTF file: {message}")]
    Parse { message: String },
    /// The reader could not give an external buffer.
    #[error("cannot read buffer {buffer} (\"{uri}\"): {message}")]
    Resource {
        buffer: usize,
        uri: String,
        message: String,
    },
    /// A `.glb` buffer that refers to a binary chunk the file does not have.
    #[error("buffer {buffer} refers to the binary chunk, which the file does not have")]
    MissingBinaryChunk { buffer: usize },
    /// A `data:` URI that is not base64 data.
    #[error("buffer {buffer} has a data URI that cannot be decoded: {message}")]
    DataUri { buffer: usize, message: String },
    /// A buffer with fewer bytes than its `byteLength`.
    #[error("buffer {buffer} has {actual} bytes, but the file says {expected}")]
    ShortBuffer {
        buffer: usize,
        expected: usize,
        actual: usize,
    },
    /// An accessor of the wrong type, or whose data lies outside its buffer.
    #[error("accessor {accessor}: {message}")]
    Accessor { accessor: usize, message: String },
    /// A sampler whose outputs do not match its inputs (cubic splines need three
    /// outputs per key).
    #[error(
        "animation \"{animation}\", sampler {sampler}: {keys} key times but {outputs} outputs \
         ({expected} expected)"
    )]
    SamplerCounts {
        animation: String,
        sampler: usize,
        keys: usize,
        outputs: usize,
        expected: usize,
    },
    /// Key times that do not increase strictly.
    #[error(
        "animation \"{animation}\", sampler {sampler}: key {index} at {time} s does not come \
         after the key before it ({previous} s)"
    )]
    TimesNotIncreasing {
        animation: String,
        sampler: usize,
        index: usize,
        previous: f64,
        time: f64,
    },
    /// A NaN or infinite number where a time, value or vertex must be.
    #[error("{what} is not a finite number")]
    NonFinite { what: String },
    /// `ShotOptions::animation` names none of the file's animations.
    #[error("the file has no animation \"{name}\"")]
    UnknownAnimation {
        name: String,
        available: Vec<String>,
    },
    /// Two animations played together drive the same property of the same node.
    #[error(
        "animations \"{first}\" and \"{second}\" both drive the {property} of node \"{node}\""
    )]
    ConflictingChannels {
        node: String,
        property: &'static str,
        first: String,
        second: String,
    },
    /// A node with two parents, or a cycle of parents.
    #[error("node {node} is not in a tree: {message}")]
    Hierarchy { node: usize, message: String },
    /// More nodes, keys, vertices or triangles, or bytes, than the limits allow.
    #[error("the file has {count} {what}, more than the {limit} allowed")]
    TooLarge {
        what: &'static str,
        count: u64,
        limit: u64,
    },
}

impl MotionError {
    /// A short stable code for the diagnostic.
    pub fn code(&self) -> &'static str {
        match self {
            MotionError::Parse { .. } => "timbre::gltf-parse",
            MotionError::Resource { .. } | MotionError::MissingBinaryChunk { .. } => {
                "timbre::gltf-buffer"
            }
            MotionError::DataUri { .. } | MotionError::ShortBuffer { .. } => "timbre::gltf-buffer",
            MotionError::Accessor { .. } => "timbre::gltf-accessor",
            MotionError::SamplerCounts { .. } | MotionError::TimesNotIncreasing { .. } => {
                "timbre::gltf-sampler"
            }
            MotionError::NonFinite { .. } => "timbre::gltf-non-finite",
            MotionError::UnknownAnimation { .. } | MotionError::ConflictingChannels { .. } => {
                "timbre::gltf-animation"
            }
            MotionError::Hierarchy { .. } => "timbre::gltf-hierarchy",
            MotionError::TooLarge { .. } => "timbre::gltf-limit",
        }
    }

    /// What to do about it.
    pub fn help(&self) -> String {
        match self {
            MotionError::Parse { .. } => {
                "give a `.glb` or `.gltf` file exported by a 3D tool (glTF 2.0); re-export it if \
                 it was cut short"
                    .into()
            }
            MotionError::Resource { uri, .. } => {
                format!("put \"{uri}\" beside the .gltf file, or export a single .glb instead")
            }
            MotionError::MissingBinaryChunk { .. }
            | MotionError::DataUri { .. }
            | MotionError::ShortBuffer { .. }
            | MotionError::Accessor { .. } => {
                "the file is damaged or was written wrongly: re-export it".into()
            }
            MotionError::SamplerCounts { .. } => {
                "each key needs one output (three for CUBICSPLINE: in-tangent, value, \
                 out-tangent); re-export the animation"
                    .into()
            }
            MotionError::TimesNotIncreasing { .. } => {
                "key times must increase strictly; remove the duplicate keys and re-export".into()
            }
            MotionError::NonFinite { .. } => {
                "re-export the file without NaN or infinite values".into()
            }
            MotionError::UnknownAnimation { available, .. } => {
                if available.is_empty() {
                    "the file has no animations".into()
                } else {
                    format!("the file's animations are: {}", quoted(available))
                }
            }
            MotionError::ConflictingChannels { first, second, .. } => {
                format!("choose one animation, e.g. \"{first}\" or \"{second}\"")
            }
            MotionError::Hierarchy { .. } => "each node may have one parent, and no cycles".into(),
            MotionError::TooLarge { .. } => {
                "simplify the scene (fewer objects, keys or polygons), or split it into shots"
                    .into()
            }
        }
    }

    /// The diagnostic, pointing at `span` (the form that read the file).
    pub fn diag(&self, span: Span) -> Diag {
        Diag::new(self.code(), self.to_string())
            .label(span, "in this file")
            .help(self.help())
    }
}

fn quoted(names: &[String]) -> String {
    names
        .iter()
        .map(|n| format!("\"{n}\""))
        .collect::<Vec<_>>()
        .join(", ")
}
