//! `timbre render --stems DIR`: beside the mix, one file per object
//! (`DIR/objects/NAME.wav`) and one per kind of sound (`DIR/kinds/NAME.wav`), which
//! sum to the mix bit for bit.
//!
//! Two partitions of one floating-point mix cannot both sum to it exactly unless the
//! arithmetic is exact, so it is made exact by construction. The instances are shared
//! out into cells (one object and one kind each); each cell is rendered on its own as
//! the whole would be (same space, gain, fade and normalising gain), and its samples
//! are rounded to the grid of the output format (`SampleFormat::steps`: 2^-24 for
//! f32, one step of the integer for s16 and s24). Every stem, and the mix, is then a
//! sum of cells in whole steps, exact in f64, and is written exactly while no sample
//! passes full scale. The mix so written differs from a render without `--stems` by
//! at most half a step per cell (and the rounding of the instances' sum).
//!
//! Every file is written to its temporary name and all are renamed into place
//! together at the end, so a render that fails or is interrupted leaves none of
//! them.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;

use rayon::prelude::*;
use timbre::{SceneFile, Stem};

use crate::audio_out::{self, OutputJob, Summary, WriteError};
use crate::output::Output;
use crate::rendering::{Pass, Plan};
use crate::Failure;

/// The stem of instances that have no label of that family.
pub(crate) const UNLABELLED: &str = "other";

/// Bytes of a label kept in its file's name.
const NAME_KEPT: usize = 100;

/// What a writer says when the render stops before its last frame.
const STOPPED: &str = "the render stopped";

/// Frames rendered per step (each cell, then every sum).
const CHUNK_FRAMES: u64 = 8192;

/// What `--stems` writes: the cells rendered and the files summed from them.
pub(crate) struct Layout {
    /// Each cell: the stem of its instances and the scene of them alone.
    cells: Vec<(Stem, SceneFile)>,
    /// Each stem file: where it goes and the cells it sums.
    files: Vec<(PathBuf, Vec<usize>)>,
}

impl Layout {
    /// The stems of `file` in `dir`, named with `extension` (the mix's).
    pub(crate) fn new(file: &SceneFile, dir: &Path, extension: &str) -> Layout {
        let cells = file.stem_cells();
        let mut files = vec![];
        for family in ["objects", "kinds"] {
            let label_of = |stem: &Stem| match family {
                "objects" => stem.object.clone(),
                _ => stem.kind.clone(),
            };
            let mut labels: Vec<Option<std::sync::Arc<str>>> = vec![];
            for (stem, _) in &cells {
                let label = label_of(stem);
                if !labels.contains(&label) {
                    labels.push(label);
                }
            }
            // The unlabelled stem is named first, so that it is always `other`.
            labels.sort_by_key(|label| label.is_some());
            let mut names = FileNames::default();
            for label in labels {
                let name = names.take(label.as_deref().unwrap_or(UNLABELLED));
                let summed = (0..cells.len())
                    .filter(|&k| label_of(&cells[k].0) == label)
                    .collect();
                files.push((dir.join(family).join(format!("{name}.{extension}")), summed));
            }
        }
        Layout { cells, files }
    }

    /// What was written, for the render's report: the stems by folder.
    pub(crate) fn report(&self, dir: &Path) -> String {
        let names = |family: &str| {
            let within = dir.join(family);
            let names: Vec<String> = (self.files.iter())
                .filter_map(|(path, _)| path.strip_prefix(&within).ok())
                .map(|name| name.display().to_string())
                .collect();
            names.join(", ")
        };
        format!(
            "wrote {} stems to {}: objects {}; kinds {}",
            self.files.len(),
            dir.display(),
            names("objects"),
            names("kinds")
        )
    }

    /// The stem files, in the order [`render`] takes their outputs.
    pub(crate) fn paths(&self) -> Vec<PathBuf> {
        self.files.iter().map(|(path, _)| path.clone()).collect()
    }
}

/// Makes `dir` and its `objects` and `kinds` folders, if they are not there.
pub(crate) fn make_dirs(dir: &Path) -> Result<(), Failure> {
    for family in ["objects", "kinds"] {
        let path = dir.join(family);
        std::fs::create_dir_all(&path).map_err(|e| {
            Failure::Message(format!(
                "cannot make the folder `{}` for the stems: {e}; choose another --stems DIR",
                path.display()
            ))
        })?;
    }
    Ok(())
}

/// File names given so far in one folder: each label becomes a name that stays in
/// the folder (no `/`, no `..`, nothing hidden), and one already given (letter case
/// aside, for file systems that ignore it) gets `-2`, `-3` … after it.
#[derive(Default)]
struct FileNames {
    given: Vec<String>,
}

impl FileNames {
    fn take(&mut self, label: &str) -> String {
        let base = safe_name(label);
        let mut name = base.clone();
        let mut k = 1;
        while self.given.iter().any(|g| g.eq_ignore_ascii_case(&name)) {
            k += 1;
            name = format!("{base}-{k}");
        }
        self.given.push(name.clone());
        name
    }
}

/// `label` as a file name: letters, digits, `-`, `_`, `.` and spaces kept, anything
/// else (`/`, `\`, `:`, control characters …) made `_`, a leading `.` too (no hidden
/// file, no `..`), at most [`NAME_KEPT`] bytes.
pub(crate) fn safe_name(label: &str) -> String {
    let mut name = String::new();
    for c in label.trim().chars() {
        let kept =
            c.is_alphanumeric() || matches!(c, '-' | '_' | ' ') || (c == '.' && !name.is_empty());
        let c = if kept { c } else { '_' };
        if name.len() + c.len_utf8() > NAME_KEPT {
            break;
        }
        name.push(c);
    }
    let name = name.trim_end().to_owned();
    if name.is_empty() {
        "_".to_owned()
    } else {
        name
    }
}

/// One cell being rendered: its pass and its last chunk, in steps of the grid.
struct Cell<'p> {
    pass: Pass<'p>,
    steps: Vec<f64>,
}

/// Renders the cells of `layout` and writes the mix into `mix` and each stem into
/// its output (`stems`, in the order of [`Layout::paths`]), `job.frames` frames, all
/// committed together once all are written. Returns the mix's summary.
pub(crate) fn render(
    plan: &Plan<'_>,
    layout: &Layout,
    mix: Output,
    stems: Vec<Output>,
    job: &OutputJob<'_>,
    scale: f64,
) -> Result<Summary, Failure> {
    // The whole scene made for the plan is not rendered: only its parts are.
    drop(plan.first_scene.lock().ok().and_then(|mut s| s.take()));
    // One cell renders on every thread; several render side by side, one thread each.
    let threads_each = if layout.cells.len() == 1 {
        plan.threads
    } else {
        1
    };
    let mut cells = vec![];
    for (k, (_, file)) in layout.cells.iter().enumerate() {
        // The first cell's progress bar shows them all, as they go in step.
        let quiet = plan.quiet || k > 0;
        let pass = Pass::of_part(plan, file, job.frames, scale, threads_each, quiet)?;
        cells.push(Cell {
            pass,
            steps: vec![],
        });
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(plan.threads.min(cells.len()).max(1))
        .build()
        .map_err(|e| Failure::Message(format!("cannot start {} threads: {e}", plan.threads)))?;
    let everything: Vec<usize> = (0..cells.len()).collect();
    let sums: Vec<&[usize]> = std::iter::once(everything.as_slice())
        .chain(layout.files.iter().map(|(_, summed)| summed.as_slice()))
        .collect();
    let outputs: Vec<Output> = std::iter::once(mix).chain(stems).collect();
    let (rendered, written) = std::thread::scope(|scope| {
        let mut senders = vec![];
        let mut writers = vec![];
        for output in outputs {
            let (sender, receiver) = mpsc::sync_channel::<Vec<f64>>(2);
            senders.push(sender);
            writers.push(scope.spawn(move || audio_out::write_held(output, job, reader(receiver))));
        }
        let rendered = feed(&mut cells, &pool, &sums, &senders, job);
        drop(senders);
        let written: Vec<_> = writers
            .into_iter()
            .map(|w| {
                w.join()
                    .unwrap_or_else(|_| Err(WriteError::Render("a writer failed".into())))
            })
            .collect();
        (rendered, written)
    });
    for cell in &cells {
        crate::report_faults(plan, &cell.pass.scene);
    }
    let beyond = rendered?;
    let (held, failed): (Vec<_>, Vec<_>) = written.into_iter().partition(Result::is_ok);
    // When one writer fails, the others stop too: its error is the one to report.
    let stopped = |e: &WriteError| matches!(e, WriteError::Render(m) if m == STOPPED);
    let mut failed: Vec<WriteError> = failed.into_iter().filter_map(Result::err).collect();
    failed.sort_by_key(stopped);
    if let Some(e) = failed.into_iter().next() {
        return Err(match e {
            WriteError::Interrupted => Failure::Interrupted,
            other => Failure::Message(other.to_string()),
        });
    }
    let held: Vec<(Summary, Output)> = held.into_iter().filter_map(Result::ok).collect();
    if beyond > 0 && !plan.quiet {
        eprintln!(
            "warning: {beyond} samples of the mix or the stems are beyond full scale, where the stems may not sum to the mix exactly (rounded as 32-bit float, or clipped); lower --gain, or use --normalize"
        );
    }
    let mut held = held.into_iter();
    let Some((summary, mix)) = held.next() else {
        return Err(Failure::Message("the mix was not written".into()));
    };
    for (_, stem) in held {
        stem.commit().map_err(Failure::Message)?;
    }
    mix.commit().map_err(Failure::Message)?;
    Ok(summary)
}

/// Renders every cell chunk by chunk and sends each sum to its writer: the cells in
/// whole steps of the grid, summed exactly, then scaled back to full scale 1. Returns
/// how many samples passed full scale.
fn feed(
    cells: &mut [Cell<'_>],
    pool: &rayon::ThreadPool,
    sums: &[&[usize]],
    senders: &[mpsc::SyncSender<Vec<f64>>],
    job: &OutputJob<'_>,
) -> Result<u64, Failure> {
    let steps = job.format.steps();
    let channels = job.channels as usize;
    let interrupted: &AtomicBool = job.interrupted;
    let (mut done, mut beyond) = (0u64, 0u64);
    while done < job.frames {
        if interrupted.load(Ordering::Relaxed) {
            return Err(Failure::Interrupted);
        }
        let n = (job.frames - done).min(CHUNK_FRAMES) as usize * channels;
        let failed = pool.install(|| {
            cells.par_iter_mut().enumerate().find_map_any(|(k, cell)| {
                cell.steps.resize(n, 0.0);
                // A cell that has ended renders silence: every cell lasts the mix's length.
                if let Err(e) = cell.pass.next(&mut cell.steps) {
                    return Some((k, e));
                }
                cell.steps
                    .iter_mut()
                    .for_each(|x| *x = (*x * steps).round());
                None
            })
        });
        if let Some((k, message)) = failed {
            return Err(cells[k].pass.failure(message));
        }
        for (summed, sender) in sums.iter().zip(senders) {
            let mut out = vec![0.0; n];
            for &k in summed.iter() {
                out.iter_mut()
                    .zip(&cells[k].steps)
                    .for_each(|(y, x)| *y += x);
            }
            beyond += out.iter().filter(|y| y.abs() > steps).count() as u64;
            out.iter_mut().for_each(|y| *y /= steps);
            if sender.send(out).is_err() {
                // The writer stopped (its error is reported).
                return Ok(beyond);
            }
        }
        done += (n / channels) as u64;
    }
    Ok(beyond)
}

/// The render function of a writer: chunks as they come from `receiver`; an error if
/// the sender stops before the writer has its frames (the render failed).
fn reader(
    receiver: mpsc::Receiver<Vec<f64>>,
) -> impl FnMut(&mut [f64]) -> Result<Option<usize>, String> {
    let mut pending: Vec<f64> = vec![];
    let mut at = 0;
    move |out: &mut [f64]| {
        let mut filled = 0;
        while filled < out.len() {
            if at == pending.len() {
                pending = receiver.recv().map_err(|_| STOPPED.to_string())?;
                at = 0;
            }
            let n = (out.len() - filled).min(pending.len() - at);
            out[filled..filled + n].copy_from_slice(&pending[at..at + n]);
            filled += n;
            at += n;
        }
        Ok(None)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_stay_in_their_folder() {
        assert_eq!(safe_name("Cube"), "Cube");
        assert_eq!(safe_name("../../etc/passwd"), "_._.._etc_passwd");
        assert_eq!(safe_name(".hidden"), "_hidden");
        assert_eq!(safe_name("a/b\\c:d\u{0}e"), "a_b_c_d_e");
        assert_eq!(safe_name("  "), "_");
        assert_eq!(safe_name("Würfel 2"), "Würfel 2");
        assert_eq!(safe_name(&"x".repeat(300)).len(), NAME_KEPT);
    }

    #[test]
    fn a_name_given_twice_is_numbered() {
        let mut names = FileNames::default();
        let taken: Vec<String> = ["other", "a/b", "a_b", "A_B", "other"]
            .into_iter()
            .map(|label| names.take(label))
            .collect();
        assert_eq!(taken, ["other", "a_b", "a_b-2", "A_B-3", "other-2"]);
    }
}
