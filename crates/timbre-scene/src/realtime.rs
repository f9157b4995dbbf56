//! The control side of a renderer split for real time (see
//! [`SceneRenderer::split`](crate::SceneRenderer::split)): instances are prepared here
//! and sent to the audio thread through a lock-free single-producer queue, and come
//! back through another when they end, to be freed here.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use timbre_ir::{Graph, NodeId, RenderConfig};
use timbre_jit::JitError;

use crate::{Engine, Fault, InstanceId, Mix, Prepared, SharedJit};

/// What the control side asks of the audio thread.
pub enum Command {
    /// An instance to add, its voice made already.
    Add {
        id: InstanceId,
        prepared: Prepared,
        start: u64,
        end: Option<u64>,
        mix: Mix,
    },
    Stop {
        id: InstanceId,
        at: u64,
    },
    Mix {
        id: InstanceId,
        mix: Mix,
    },
}

/// An instance that has ended, sent back from the audio thread with its voice so that
/// the voice is freed on the control side.
pub struct Ended {
    pub id: InstanceId,
    /// Its samples that were not finite, if any (left out of the mix).
    pub fault: Option<Fault>,
    /// Its voice (none for a lane of a batch, which stays with the renderer).
    pub(crate) voice: Option<Prepared>,
}

/// Why the control side refused a command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refused {
    /// As many instances are playing or waiting to start as the split allows.
    TooManyInstances { limit: usize },
    /// The audio thread has not taken the commands already sent (it is not rendering).
    QueueFull,
}

impl std::fmt::Display for Refused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refused::TooManyInstances { limit } => {
                write!(
                    f,
                    "{limit} instances are playing or waiting to start already"
                )
            }
            Refused::QueueFull => write!(f, "the audio thread is not taking commands"),
        }
    }
}

impl std::error::Error for Refused {}

pub(crate) struct Parts {
    pub commands: rtrb::Producer<Command>,
    pub ended: rtrb::Consumer<Ended>,
    pub position: Arc<AtomicU64>,
    pub next_id: u64,
    pub alive: usize,
    pub capacity: usize,
    pub engine: Engine,
    pub jit: Option<SharedJit>,
    pub config: RenderConfig,
    pub channels: usize,
}

/// The control side of a split renderer: prepares instances (lowered trees to voices,
/// compiling kernels the cache lacks) and sends them, with stops and mix changes, to
/// the audio thread. One owner at a time (it is `Send`); a host that controls from
/// several threads puts it behind a lock, which the audio thread never takes.
pub struct Control {
    parts: Parts,
    faults: Vec<Fault>,
}

impl Control {
    pub(crate) fn new(parts: Parts) -> Self {
        Control {
            parts,
            faults: vec![],
        }
    }

    /// Makes the voice of `root` of `graph`, here rather than on the audio thread.
    pub fn prepare(&self, graph: &Graph, root: NodeId) -> Result<Prepared, JitError> {
        let p = &self.parts;
        Prepared::new(p.engine, p.jit.as_ref(), p.config, graph, root)
    }

    /// Sends a prepared instance starting at scene sample `start` (a start already
    /// past begins at the next block), ending at `end` or once it has decayed.
    pub fn add(
        &mut self,
        prepared: Prepared,
        start: u64,
        end: Option<u64>,
        mix: Mix,
    ) -> Result<InstanceId, Refused> {
        self.collect();
        let limit = self.parts.capacity;
        if self.parts.alive >= limit {
            return Err(Refused::TooManyInstances { limit });
        }
        self.parts.next_id += 1;
        let id = InstanceId(self.parts.next_id);
        let command = Command::Add {
            id,
            prepared,
            start,
            end,
            mix,
        };
        self.send(command)?;
        self.parts.alive += 1;
        Ok(id)
    }

    /// Stops an instance at scene sample `at` (not before the next block) with the
    /// short fade-out.
    pub fn stop(&mut self, id: InstanceId, at: u64) -> Result<(), Refused> {
        self.collect();
        self.send(Command::Stop { id, at })
    }

    /// Changes where an instance is heard, from the next block.
    pub fn set_mix(&mut self, id: InstanceId, mix: Mix) -> Result<(), Refused> {
        self.collect();
        self.send(Command::Mix { id, mix })
    }

    fn send(&mut self, command: Command) -> Result<(), Refused> {
        self.parts
            .commands
            .push(command)
            .map_err(|_| Refused::QueueFull)
    }

    /// Takes the instances that have ended back from the audio thread, freeing their
    /// voices here and keeping their faults. Every call of the control side does it.
    pub fn collect(&mut self) {
        while let Ok(ended) = self.parts.ended.pop() {
            self.parts.alive -= 1;
            self.faults.extend(ended.fault);
            drop(ended.voice);
        }
    }

    /// Scene sample the audio thread will render next (as of its last block).
    pub fn position(&self) -> u64 {
        self.parts.position.load(Ordering::Acquire)
    }

    /// Instances sent and not yet known to have ended.
    pub fn alive(&self) -> usize {
        self.parts.alive
    }

    /// Instances that ended after producing samples that were not finite.
    pub fn faults(&self) -> &[Fault] {
        &self.faults
    }

    pub fn config(&self) -> RenderConfig {
        self.parts.config
    }

    pub fn channels(&self) -> usize {
        self.parts.channels
    }
}
