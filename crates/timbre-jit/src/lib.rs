//! Compiles timbre trees into native block kernels with cranelift.
//!
//! A [`Jit`] compiles the schedule of a tree (after lowering, and later after
//! instantiation) into one native function per tree *shape*. Pure element-wise
//! nodes are fused into SIMD loops over lanes and pairs of samples; every other
//! node is computed by calling back into the reference interpreter, so each node has
//! exactly one definition of its semantics. Constants, states (noise seeds among
//! them) and the sample rate are reached through pointers, so instances of one
//! shape share one kernel and a new instance costs no compilation. Kernels are
//! compiled into *generations* of bounded size, and a generation's code is freed
//! when its last kernel is dropped (see [`Jit`]).
//!
//! This crate is *not* a second semantics: the interpreter in `timbre-ir` is the
//! reference, and the tests compare the two at every sample.

mod approx;
mod codegen;
mod lanes;
mod modal;
mod plan;
mod shape;
mod timer;

use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use cranelift_codegen::ir::{AbiParam, InstBuilder, MemFlagsData, Signature};
use cranelift_codegen::isa::OwnedTargetIsa;
use cranelift_codegen::settings::{self, Configurable};
use cranelift_codegen::Context;
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext};
use cranelift_jit::{JITBuilder, JITModule};
use cranelift_module::{FuncId, Linkage, Module};
use timbre_ir::op::Op;
use timbre_ir::{Graph, Interpreter, NodeId, RenderConfig, Step};

use crate::codegen::{kernel_signature, Helpers, KernelBuilder, NOISE_SEED, NOISE_SLOTS};
use crate::plan::PlanStep;
use crate::shape::{is_modal_bank, Shape};

pub use crate::lanes::{InstanceLanes, LaneBatch, BATCH_LANES};
#[doc(hidden)]
pub use crate::modal::ModalPath;

/// Why a tree could not be compiled.
#[derive(Debug, thiserror::Error)]
pub enum JitError {
    #[error("this machine is not supported by the code generator: {0}")]
    Host(String),
    #[error("code generation failed: {0}")]
    Codegen(String),
    /// The tree has more than [`MAX_KERNEL_STEPS`] nodes to compute: render it with the
    /// interpreter.
    #[error("a tree of {steps} nodes is too large to compile (at most {MAX_KERNEL_STEPS})")]
    TooLarge { steps: usize },
}

/// The most nodes one kernel computes. The code generator's time and memory grow with
/// the number of nodes (about 10 KB each while compiling), and a 1 KB file can build a
/// tree of millions; larger trees are refused with [`JitError::TooLarge`] rather than
/// exhausting memory. Realistic trees are far smaller: lanes make a thousand modes one
/// node.
pub const MAX_KERNEL_STEPS: usize = 1 << 14;

/// `kernel(interp, buffers, params, n, t0, states)`; see `codegen`.
type KernelFn =
    unsafe extern "C" fn(*mut Interpreter, *const *mut f64, *const f64, u64, u64, *const *mut f64);

/// A compiled tree shape.
pub struct Kernel {
    entry: KernelFn,
    /// Time spent compiling it.
    pub compile_time: Duration,
    /// Nodes computed inline, and nodes left to the interpreter.
    pub inline_nodes: usize,
    pub callback_nodes: usize,
    /// Steps whose splatted copies the kernel keeps (`plan::Region::splatted`), in
    /// the state table after the states, at `steps + step`: room for two values per
    /// sample of a block.
    splatted: Vec<usize>,
    /// The module holding `entry`'s code, which lives as long as this.
    _generation: Arc<Generation>,
}

impl std::fmt::Debug for Kernel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Kernel")
            .field("compile_time", &self.compile_time)
            .field("inline_nodes", &self.inline_nodes)
            .field("callback_nodes", &self.callback_nodes)
            .finish()
    }
}

/// Kernels compiled into one generation (one cranelift module) before the [`Jit`]
/// starts the next: the bound on the code its cache keeps alive.
pub const KERNELS_PER_GENERATION: usize = 256;

/// The compiler: a cache of kernels by tree shape, and the generated code.
///
/// Kernels are compiled into *generations*, one cranelift module each (cranelift
/// frees code only by freeing its whole module). When the current generation holds
/// [`KERNELS_PER_GENERATION`] kernels, the next kernel starts a new generation and
/// the cache forgets the old one's kernels (a later voice of such a shape compiles it
/// again). A generation's code is freed when the last [`Kernel`] compiled into it is
/// dropped: each kernel holds its generation, and each [`JitVoice`] its kernel, so
/// voices may outlive their `Jit`, and a long-running host keeps the code of at most
/// one full generation for its cache plus the generations its live voices use.
pub struct Jit {
    isa: OwnedTargetIsa,
    /// Where new kernels are compiled.
    generation: Arc<Generation>,
    /// Kernels compiled into `generation`.
    generation_kernels: usize,
    kernels_per_generation: usize,
    context: Context,
    builder_context: FunctionBuilderContext,
    /// Kernels of the current generation, by shape.
    cache: HashMap<Shape, Arc<Kernel>>,
    next_name: usize,
    kernels_compiled: usize,
    /// Generations of this `Jit` not yet freed.
    live_generations: Arc<AtomicUsize>,
    /// Modal banks' tables, shared by the voices of the same modes.
    modal_tables: modal::TableCache,
    /// How the modal banks of new voices compute their tiles.
    modal_lanes: modal::Lanes,
}

/// One cranelift module: some kernels' code, freed when the last of them is dropped.
struct Generation {
    /// In a mutex so that the last kernel may free it on any thread (a module is
    /// `Send`, not `Sync`); only the `Jit` locks it, to compile. `None` only while
    /// it is freed.
    module: Mutex<Option<JITModule>>,
    /// The helper functions kernels call, declared in this module.
    helpers: [FuncId; 5],
    live: Arc<AtomicUsize>,
}

impl Generation {
    fn new(isa: &OwnedTargetIsa, live: &Arc<AtomicUsize>) -> Result<Self, JitError> {
        let mut builder =
            JITBuilder::with_isa(isa.clone(), cranelift_module::default_libcall_names());
        builder.symbol("timbre_step", step_callback as *const u8);
        builder.symbol("timbre_unary", codegen::call_unary as *const u8);
        builder.symbol("timbre_binary", codegen::call_binary as *const u8);
        builder.symbol("timbre_modal_block", modal::modal_block as *const u8);
        builder.symbol("timbre_timer_block", timer::timer_block as *const u8);
        let mut module = JITModule::new(builder);
        let call_conv = module.target_config().default_call_conv;
        use cranelift_codegen::ir::types::{F64, I64};
        let signature = |params: &[cranelift_codegen::ir::Type], returns: Option<_>| {
            let mut sig = Signature::new(call_conv);
            sig.params.extend(params.iter().map(|t| AbiParam::new(*t)));
            sig.returns.extend(returns.map(AbiParam::new));
            sig
        };
        let declare = |module: &mut JITModule, name: &str, sig: Signature| {
            module
                .declare_function(name, Linkage::Import, &sig)
                .map_err(|e| JitError::Codegen(e.to_string()))
        };
        let helpers = [
            declare(
                &mut module,
                "timbre_step",
                signature(&[I64, I64, I64], None),
            )?,
            declare(
                &mut module,
                "timbre_unary",
                signature(&[I64, F64], Some(F64)),
            )?,
            declare(
                &mut module,
                "timbre_binary",
                signature(&[I64, F64, F64], Some(F64)),
            )?,
            declare(
                &mut module,
                "timbre_modal_block",
                signature(&[I64; 5], None),
            )?,
            declare(
                &mut module,
                "timbre_timer_block",
                signature(&[I64; 8], None),
            )?,
        ];
        live.fetch_add(1, Ordering::Relaxed);
        Ok(Generation {
            module: Mutex::new(Some(module)),
            helpers,
            live: live.clone(),
        })
    }
}

impl Drop for Generation {
    fn drop(&mut self) {
        let module = self
            .module
            .get_mut()
            .unwrap_or_else(PoisonError::into_inner)
            .take();
        if let Some(module) = module {
            // SAFETY: the module's code is reached only through `Kernel::entry`, every
            // kernel holds its generation, and a kernel runs only within
            // `JitVoice::render`, which borrows the voice and so its kernel. This was
            // the last reference: none of the code is running or can be called.
            unsafe { module.free_memory() };
        }
        self.live.fetch_sub(1, Ordering::Relaxed);
    }
}

impl Jit {
    /// A compiler whose generations hold [`KERNELS_PER_GENERATION`] kernels.
    pub fn new() -> Result<Self, JitError> {
        Self::with_kernels_per_generation(KERNELS_PER_GENERATION)
    }

    /// A compiler whose generations hold `kernels` kernels (at least one).
    pub fn with_kernels_per_generation(kernels: usize) -> Result<Self, JitError> {
        let mut flags = settings::builder();
        // No cranelift optimiser: the plan and the code generator already fold,
        // share and hoist (see `docs/architecture.md`), and the optimiser's code
        // motion lengthens live ranges in the sixteen vector registers: the swarm
        // ran 10 % slower with it, nothing ran faster, and compiling took longer.
        // Cranelift's IR verifier checks every function it compiles: kept in debug
        // builds (`cargo test` without `--release`), left out of release builds,
        // where it was about a quarter of the compile time.
        let verify = if cfg!(debug_assertions) {
            "true"
        } else {
            "false"
        };
        for (name, value) in [
            ("opt_level", "none"),
            ("use_colocated_libcalls", "false"),
            ("is_pic", "false"),
            ("enable_verifier", verify),
        ] {
            flags
                .set(name, value)
                .map_err(|e| JitError::Host(e.to_string()))?;
        }
        let isa = cranelift_native::builder()
            .map_err(|e| JitError::Host(e.to_string()))?
            .finish(settings::Flags::new(flags))
            .map_err(|e| JitError::Host(e.to_string()))?;
        let live_generations = Arc::new(AtomicUsize::new(0));
        let generation = Arc::new(Generation::new(&isa, &live_generations)?);
        let mut context = Context::new();
        context.func.signature.call_conv = isa.default_call_conv();
        Ok(Jit {
            isa,
            generation,
            generation_kernels: 0,
            kernels_per_generation: kernels.max(1),
            context,
            builder_context: FunctionBuilderContext::new(),
            cache: HashMap::new(),
            next_name: 0,
            kernels_compiled: 0,
            live_generations,
            modal_tables: modal::TableCache::default(),
            modal_lanes: modal::Lanes::best(),
        })
    }

    /// Computes the modal banks of the voices made from now on with `path` (the
    /// widest this CPU runs, [`ModalPath::best`], unless set): every path gives the
    /// same samples, bit for bit, so this is for tests and measurements. A path whose
    /// instructions this CPU lacks is refused, and the current one kept.
    #[doc(hidden)]
    pub fn set_modal_path(&mut self, path: ModalPath) -> Result<(), JitError> {
        self.modal_lanes = modal::Lanes::new(path).ok_or_else(|| {
            JitError::Host(format!("this CPU cannot compute modal banks with {path:?}"))
        })?;
        Ok(())
    }

    /// How the modal banks of new voices compute their tiles.
    #[doc(hidden)]
    pub fn modal_path(&self) -> ModalPath {
        self.modal_lanes.path()
    }

    /// Starts a new generation: the cache forgets the current one's kernels, whose
    /// code lives on while kernels compiled into it do.
    fn start_generation(&mut self) -> Result<(), JitError> {
        self.cache.clear();
        self.generation = Arc::new(Generation::new(&self.isa, &self.live_generations)?);
        self.generation_kernels = 0;
        Ok(())
    }

    /// Compiles (or finds in the cache) the kernel of a schedule of at most
    /// [`MAX_KERNEL_STEPS`] steps.
    pub fn compile(&mut self, steps: &[Step], block_size: usize) -> Result<Arc<Kernel>, JitError> {
        if steps.len() > MAX_KERNEL_STEPS {
            return Err(JitError::TooLarge { steps: steps.len() });
        }
        let shape = Shape::of(steps, block_size);
        if let Some(kernel) = self.cache.get(&shape) {
            return Ok(kernel.clone());
        }
        if self.generation_kernels >= self.kernels_per_generation {
            self.start_generation()?;
        }
        let start = Instant::now();
        let generation = self.generation.clone();
        let mut module = generation
            .module
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let Some(module) = module.as_mut() else {
            unreachable!("a generation's module is taken only when it is dropped")
        };
        let plan = plan::plan(steps);
        let splatted = splatted_steps(&plan, steps.len());
        let call_conv = module.target_config().default_call_conv;
        self.context.func.signature = kernel_signature(call_conv);
        {
            let mut b = FunctionBuilder::new(&mut self.context.func, &mut self.builder_context);
            let entry = b.create_block();
            b.append_block_params_for_function_params(entry);
            b.switch_to_block(entry);
            let params = b.block_params(entry).to_vec();
            let [step, unary, binary, modal_block, timer_block] = generation
                .helpers
                .map(|helper| module.declare_func_in_func(helper, b.func));
            let helpers = Helpers {
                step,
                unary,
                binary,
                modal_block,
                timer_block,
            };
            let param = |b: &mut FunctionBuilder, ty, k: i32| {
                b.ins()
                    .load(ty, MemFlagsData::new().with_notrap(), params[2], 8 * k)
            };
            use cranelift_codegen::ir::types::{F64, I64};
            let sample_rate = param(&mut b, F64, 0);
            let sample_period = param(&mut b, F64, 1);
            let lane_starts = param(&mut b, I64, 2);
            let lanes_in_use = param(&mut b, I64, 3);
            let mut kb = KernelBuilder {
                b: &mut b,
                steps,
                helpers,
                block_size,
                interp: params[0],
                buffers: params[1],
                n: params[3],
                t0: params[4],
                states: params[5],
                sample_rate,
                sample_period,
                lane_starts,
                lanes_in_use,
                splatted: splatted.clone(),
            };
            kb.emit(&plan);
            b.ins().return_(&[]);
            b.seal_all_blocks();
            b.finalize(module.target_config());
        }
        let name = format!("kernel{}", self.next_name);
        self.next_name += 1;
        let id = module
            .declare_function(&name, Linkage::Local, &self.context.func.signature)
            .map_err(|e| JitError::Codegen(e.to_string()))?;
        let defined = module.define_function(id, &mut self.context);
        module.clear_context(&mut self.context);
        defined.map_err(|e| JitError::Codegen(format!("{e:?}")))?;
        module
            .finalize_definitions()
            .map_err(|e| JitError::Codegen(e.to_string()))?;
        let code = module.get_finalized_function(id);
        let (inline_nodes, callback_nodes) = plan.iter().fold((0, 0), |(i, c), step| match step {
            PlanStep::Region(r) => (i + r.nodes.len() + r.combines.len(), c),
            PlanStep::ModalBank(_) | PlanStep::Timer(_) => (i + 1, c),
            PlanStep::Callback(_) => (i, c + 1),
        });
        let splatted = splatted
            .iter()
            .enumerate()
            .filter_map(|(s, &yes)| yes.then_some(s))
            .collect();
        let kernel = Arc::new(Kernel {
            // SAFETY: `code` was generated with `kernel_signature`, which matches
            // `KernelFn`, and stays valid while its generation lives, which the
            // kernel holds.
            entry: unsafe { std::mem::transmute::<*const u8, KernelFn>(code) },
            compile_time: start.elapsed(),
            inline_nodes,
            callback_nodes,
            splatted,
            _generation: generation.clone(),
        });
        self.generation_kernels += 1;
        self.kernels_compiled += 1;
        self.cache.insert(shape, kernel.clone());
        Ok(kernel)
    }

    /// A voice of `root` rendered by a compiled kernel, after the rewrites of
    /// [`timbre_ir::optimise`]. A tree of more than [`MAX_KERNEL_STEPS`] nodes is
    /// [`JitError::TooLarge`].
    pub fn voice(
        &mut self,
        graph: &Graph,
        root: NodeId,
        config: RenderConfig,
    ) -> Result<JitVoice, JitError> {
        self.finish_voice(VoiceDraft::new(graph, root, config)?)
    }

    /// The voice of `draft`: its kernel from the cache (or compiled), its states.
    pub fn finish_voice(&mut self, draft: VoiceDraft) -> Result<JitVoice, JitError> {
        let VoiceDraft { mut interp, config } = draft;
        let kernel = self.compile(interp.steps(), config.block_size)?;
        let buffers = interp.buffer_pointers();
        // State of the nodes computed inline: one phase per lane of each phasor; the
        // floor of the last lattice cell (none yet: NaN equals nothing), its five
        // polynomial coefficients and the seed per lane of each noise; the seed of each
        // white noise; two partial sums
        // per sample of each combine (used when its argument is summed in a lane
        // region).
        let no_cell = f64::NAN;
        let mut states: Vec<Vec<f64>> = interp
            .steps()
            .iter()
            .map(|s| match s.op {
                Op::Phasor => vec![0.0; s.width],
                Op::Noise { ref seeds } => {
                    // Slot-major: each slot's lanes side by side (see NOISE_SLOTS).
                    let lanes = s.width;
                    let mut state = vec![0.0; NOISE_SLOTS * lanes];
                    state[..lanes].fill(no_cell);
                    // The bits of each lane's mixed seed, which the kernel loads as an
                    // integer.
                    for (slot, seed) in state[NOISE_SEED * lanes..].iter_mut().zip(seeds.iter()) {
                        *slot = f64::from_bits(timbre_ir::dsp::noise::mix64(*seed));
                    }
                    state
                }
                // The bits of each lane's mixed seed, as for a noise.
                Op::White { ref seeds } => seeds
                    .iter()
                    .map(|seed| f64::from_bits(timbre_ir::dsp::noise::mix64(*seed)))
                    .collect(),
                Op::Combine => vec![0.0; 2 * config.block_size],
                Op::Timer {
                    length,
                    fade_in,
                    fade_out,
                } => timer::state(length, fade_in, fade_out, config.sample_rate, s.width),
                _ => vec![],
            })
            .collect();
        // After them, one entry per step: the splatted copies of the steps that have
        // them (see `Kernel::splatted`).
        let mut copies = vec![vec![]; states.len()];
        for &s in &kernel.splatted {
            // One sample more than a block: lane regions read a sample ahead.
            copies[s] = vec![0.0; 2 * (config.block_size + 1)];
        }
        states.extend(copies);
        let mut state_pointers: Vec<*mut f64> = states.iter_mut().map(|s| s.as_mut_ptr()).collect();
        // Modal banks keep a state of their own (see `modal::ModalState`).
        let mut modal_banks: Vec<(usize, modal::ModalState)> = interp
            .steps()
            .iter()
            .enumerate()
            .filter(|(_, step)| is_modal_bank(interp.steps(), step))
            .map(|(i, step)| {
                let state = modal::ModalState::new(
                    interp.steps(),
                    step,
                    config,
                    &mut self.modal_tables,
                    self.modal_lanes,
                );
                (i, state)
            })
            .collect();
        for (i, bank) in &mut modal_banks {
            state_pointers[*i] = (bank as *mut modal::ModalState).cast();
        }
        // Its lanes all start with it (see `KernelBuilder::lane_starts`).
        let widest = interp.steps().iter().map(|s| s.width).max().unwrap_or(1);
        let lane_starts = vec![0i64; widest];
        let params = kernel_params(config.sample_rate, &lane_starts, widest);
        Ok(JitVoice {
            root_width: interp.root_width(),
            interp,
            kernel,
            buffers,
            _states: states,
            modal_banks,
            state_pointers,
            _lane_starts: lane_starts,
            params,
        })
    }

    /// Kernels in the cache (those of the current generation).
    pub fn cached_kernels(&self) -> usize {
        self.cache.len()
    }

    /// Kernels compiled so far, over every generation.
    pub fn kernels_compiled(&self) -> usize {
        self.kernels_compiled
    }

    /// Generations whose code is not yet freed: the current one, and those that
    /// kernels still in use were compiled into.
    pub fn live_generations(&self) -> usize {
        self.live_generations.load(Ordering::Relaxed)
    }
}

/// What a voice is made of before its kernel: the tree optimised and laid out in
/// blocks. It needs no [`Jit`], so the voices of instances about to start can be
/// drafted on several threads at once; [`Jit::finish_voice`] then takes the kernel.
pub struct VoiceDraft {
    interp: Interpreter,
    config: RenderConfig,
}

impl VoiceDraft {
    /// The draft of [`Jit::voice`]'s voice of `root`.
    pub fn new(graph: &Graph, root: NodeId, config: RenderConfig) -> Result<Self, JitError> {
        let steps = graph.schedule(root).len();
        if steps > MAX_KERNEL_STEPS {
            return Err(JitError::TooLarge { steps });
        }
        // Pairs of samples are computed together: the block holds a whole number of them.
        let config = RenderConfig {
            block_size: config.block_size.max(2).div_ceil(2) * 2,
            ..config
        };
        let (graph, root) = timbre_ir::optimise::optimise(graph, root);
        let interp = Interpreter::new(&graph, root, config);
        Ok(VoiceDraft { interp, config })
    }
}

/// An instance of a compiled tree: its own buffers and states, a shared kernel.
pub struct JitVoice {
    interp: Interpreter,
    /// Shared with the other voices of its shape; keeps its generation's code alive.
    kernel: Arc<Kernel>,
    /// Step buffers of `interp`, for the kernel.
    buffers: Vec<*mut f64>,
    /// State of nodes computed inline, owned here and reached by the kernel through
    /// `state_pointers`.
    _states: Vec<Vec<f64>>,
    modal_banks: Vec<(usize, modal::ModalState)>,
    /// The interpreter's, kept here: a scene asks for it every block, and a voice's
    /// interpreter is cold in the cache when it has a thousand others.
    root_width: usize,
    state_pointers: Vec<*mut f64>,
    /// Reached through `params`.
    _lane_starts: Vec<i64>,
    params: [f64; 4],
}

/// A kernel's parameter table: the sample rate, the interpreter's own sample period
/// (bit for bit), where the lanes' starts are and how many lanes are in use (see
/// `KernelBuilder`), the last two as the bits of integers.
fn kernel_params(sample_rate: f64, lane_starts: &[i64], lanes_in_use: usize) -> [f64; 4] {
    [
        sample_rate,
        1.0 / sample_rate,
        f64::from_bits(lane_starts.as_ptr() as u64),
        f64::from_bits(lanes_in_use as u64),
    ]
}

// SAFETY: the raw pointers point into buffers owned by this voice's interpreter and
// are used only by this voice.
unsafe impl Send for JitVoice {}

impl JitVoice {
    pub fn kernel(&self) -> &Kernel {
        &self.kernel
    }

    /// Shares the modes of its large modal banks out among `pool`'s threads (or not,
    /// with `None`). Each group of modes is summed apart and the groups are added in
    /// order, so the samples are the same, bit for bit, whatever the threads.
    pub fn set_threads(&mut self, pool: Option<Arc<rayon::ThreadPool>>) {
        for (_, bank) in &mut self.modal_banks {
            bank.set_pool(pool.clone());
        }
    }

    /// Lanes of the root: the frames [`JitVoice::render_frames`] writes.
    pub fn root_width(&self) -> usize {
        self.root_width
    }

    /// Renders the next `out.len()` samples (of a one-lane root).
    pub fn render(&mut self, out: &mut [f64]) {
        let block = self.interp.config().block_size;
        for chunk in out.chunks_mut(block) {
            let n = chunk.len();
            self.render_block(n);
            chunk.copy_from_slice(self.interp.root_output(n));
        }
    }

    /// Renders the next `out.len() / root_width` samples of every lane of the root,
    /// interleaved.
    pub fn render_frames(&mut self, out: &mut [f64]) {
        let width = self.root_width();
        if width == 1 {
            return self.render(out);
        }
        let block = self.interp.config().block_size;
        for chunk in out.chunks_mut(block * width) {
            let n = chunk.len() / width;
            self.render_block(n);
            self.interp.interleave_root(n, chunk);
        }
    }

    /// Computes the next `n ≤ block_size` samples into the step buffers.
    fn render_block(&mut self, n: usize) {
        let t0 = self.interp.position();
        // SAFETY: the buffer table holds one valid buffer of `width × block`
        // samples per step (with room for the last pair), and the interpreter
        // pointer is exclusive for the call: callbacks re-enter it only to compute
        // steps whose buffers the kernel is not reading or writing at that time.
        unsafe {
            (self.kernel.entry)(
                &mut self.interp,
                self.buffers.as_ptr(),
                self.params.as_ptr(),
                n as u64,
                t0,
                self.state_pointers.as_ptr(),
            );
        }
        self.interp.advance(n);
    }
}

/// Per step: whether a region of the plan keeps splatted copies of it.
fn splatted_steps(plan: &[PlanStep], steps: usize) -> Vec<bool> {
    let mut splatted = vec![false; steps];
    for step in plan {
        if let PlanStep::Region(region) = step {
            for &s in &region.splatted {
                splatted[s] = true;
            }
        }
    }
    splatted
}

/// Computes one step in the interpreter; called by kernels.
extern "C" fn step_callback(interp: *mut Interpreter, step: u64, n: u64) {
    // SAFETY: kernels pass the interpreter they were called with.
    let interp = unsafe { &mut *interp };
    if profile::ENABLED.load(Ordering::Relaxed) {
        let start = Instant::now();
        interp.eval_step(step as usize, n as usize);
        profile::record(start.elapsed());
    } else {
        interp.eval_step(step as usize, n as usize);
    }
}

/// How much of a kernel's time goes to interpreter callbacks: the nodes it does not
/// compile. Off unless a benchmark turns it on; then every callback (one per step and
/// block) is timed, process-wide.
pub mod profile {
    use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
    use std::time::Duration;

    pub(crate) static ENABLED: AtomicBool = AtomicBool::new(false);
    static CALLBACK_NANOS: AtomicU64 = AtomicU64::new(0);

    /// Starts (or stops) timing callbacks.
    pub fn enable(on: bool) {
        ENABLED.store(on, Ordering::Relaxed);
    }

    /// The time spent in callbacks since the last call, and resets it.
    pub fn take() -> Duration {
        Duration::from_nanos(CALLBACK_NANOS.swap(0, Ordering::Relaxed))
    }

    pub(crate) fn record(time: Duration) {
        CALLBACK_NANOS.fetch_add(time.as_nanos() as u64, Ordering::Relaxed);
    }
}
