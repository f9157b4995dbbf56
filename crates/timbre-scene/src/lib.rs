//! Sonic scenes: the instances of a compiled program, each switched on at its start
//! sample and off after its stop (or once it has decayed to silence), summed and
//! rendered block by block so memory does not grow with the scene's length.
//!
//! This crate does not parse or lower: `timbre-ir` turns `define-sound`, `keyframes`
//! and `instance` forms into one graph with a timer-topped root per instance. It is
//! not yet the embedding API (starting instances from code arrives with `timbre`).

use std::sync::Arc;

use timbre_ir::{Graph, Instance, Interpreter, NodeId, Program, RenderConfig, DECLICK_OUT};
use timbre_jit::{Jit, JitError, JitVoice};

/// Which engine renders the instances.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Engine {
    Jit,
    Interpreter,
}

/// Output below this is silence, for ending instances that have decayed (−120 dBFS).
const SILENCE: f64 = 1e-6;
/// An instance with no stop ends after this long below [`SILENCE`], once heard.
const SILENT_SECONDS: f64 = 0.1;

enum Voice {
    Interpreter(Interpreter),
    Jit(JitVoice),
}

impl Voice {
    fn render(&mut self, out: &mut [f64]) {
        match self {
            Voice::Interpreter(v) => v.render(out),
            Voice::Jit(v) => v.render(out),
        }
    }
}

struct Pending {
    root: NodeId,
    /// Whether it ends once it has decayed to silence (instances without a stop do;
    /// a file's one sound plays to the end).
    ends_when_silent: bool,
    start: u64,
    /// First sample after the instance (its stop plus the fade-out), if it stops.
    end: Option<u64>,
}

struct Active {
    voice: Voice,
    /// Scene sample of the voice's next sample.
    next: u64,
    end: Option<u64>,
    ends_when_silent: bool,
    heard: bool,
    silent_samples: u64,
}

/// Renders a scene: the sum of its instances, mono.
pub struct SceneRenderer {
    graph: Arc<Graph>,
    config: RenderConfig,
    engine: Engine,
    jit: Option<Jit>,
    /// Instances not started yet, latest start first (so the next is at the end).
    pending: Vec<Pending>,
    active: Vec<Active>,
    position: u64,
    scratch: Vec<f64>,
    silent_limit: u64,
}

impl SceneRenderer {
    /// A renderer of `program`'s instances (or of its one sound, as an instance
    /// starting at 0).
    pub fn new(program: &Program, config: RenderConfig, engine: Engine) -> Result<Self, JitError> {
        let sr = config.sample_rate;
        let mut pending: Vec<Pending> = match (&program.root, program.instances.as_slice()) {
            (Some(root), _) => vec![Pending {
                root: *root,
                ends_when_silent: false,
                start: 0,
                end: None,
            }],
            (None, instances) => instances.iter().map(|i| pending(i, sr)).collect(),
        };
        pending.sort_by_key(|p| std::cmp::Reverse(p.start));
        let jit = match engine {
            Engine::Jit => Some(Jit::new()?),
            Engine::Interpreter => None,
        };
        Ok(SceneRenderer {
            graph: Arc::new(program.graph.clone()),
            config,
            engine,
            jit,
            pending,
            active: vec![],
            position: 0,
            scratch: vec![0.0; config.block_size.max(1)],
            silent_limit: (SILENT_SECONDS * sr) as u64,
        })
    }

    /// Samples rendered so far.
    pub fn position(&self) -> u64 {
        self.position
    }

    /// Instances playing now.
    pub fn active_instances(&self) -> usize {
        self.active.len()
    }

    /// Renders the next `out.len()` samples of the scene.
    pub fn render(&mut self, out: &mut [f64]) -> Result<(), JitError> {
        let block = self.config.block_size.max(1);
        for chunk in out.chunks_mut(block) {
            self.render_block(chunk)?;
        }
        Ok(())
    }

    fn render_block(&mut self, out: &mut [f64]) -> Result<(), JitError> {
        out.fill(0.0);
        let end = self.position + out.len() as u64;
        while self.pending.last().is_some_and(|p| p.start < end) {
            let Some(p) = self.pending.pop() else { break };
            let voice = match (self.engine, &mut self.jit) {
                (Engine::Jit, Some(jit)) => {
                    Voice::Jit(jit.voice(&self.graph, p.root, self.config)?)
                }
                _ => Voice::Interpreter(Interpreter::new(&self.graph, p.root, self.config)),
            };
            self.active.push(Active {
                voice,
                next: p.start,
                end: p.end,
                ends_when_silent: p.ends_when_silent,
                heard: false,
                silent_samples: 0,
            });
        }
        let silent_limit = self.silent_limit;
        for active in &mut self.active {
            // Sample-accurate start: the first block of a voice may begin mid-block.
            let from = active.next.max(self.position);
            let until = active.end.map_or(end, |e| e.min(end));
            if until <= from {
                continue;
            }
            let offset = (from - self.position) as usize;
            let n = (until - from) as usize;
            let scratch = &mut self.scratch[..n];
            active.voice.render(scratch);
            for (y, x) in out[offset..offset + n].iter_mut().zip(scratch.iter()) {
                *y += x;
                if x.abs() >= SILENCE {
                    active.heard = true;
                    active.silent_samples = 0;
                } else {
                    active.silent_samples += 1;
                }
            }
            active.next = until;
        }
        self.active.retain(|a| {
            let stopped = a.end.is_some_and(|e| a.next >= e);
            let decayed = a.ends_when_silent
                && a.end.is_none()
                && a.heard
                && a.silent_samples >= silent_limit;
            !(stopped || decayed)
        });
        self.position = end;
        Ok(())
    }
}

fn pending(instance: &Instance, sr: f64) -> Pending {
    let start = (instance.start * sr).round() as u64;
    let end = instance
        .stop
        .map(|stop| ((stop + DECLICK_OUT) * sr).round() as u64);
    Pending {
        root: instance.root,
        ends_when_silent: true,
        start,
        end,
    }
}
