//! Hostile input: every file of `tests/hostile/` (each says on its second line what
//! it must give: `; expect: CODE` or `; expect: ok`), and inputs too large to keep in
//! the repository, made here. Each is rendered under a 4 GiB address-space cap and a
//! time limit, and must end with its diagnostic (or render), never with a panic, an
//! abort, a signal, a hang or a flood of output.

mod common;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{command_in_shell, strip_ansi, workspace_root};

/// The address space each run may use, in KiB (`ulimit -v`).
const MEMORY_CAP_KIB: u64 = 4 << 20;
const TIME_LIMIT: Duration = Duration::from_secs(60);
/// The most a report may print.
const MAX_REPORT_BYTES: usize = 64 << 10;

struct Outcome {
    code: Option<i32>,
    stderr: String,
    took: Duration,
}

/// Runs `timbre ARGS…` in `dir` under the memory cap, killing it at the time limit.
fn run_capped(dir: &Path, args: &[&str], stdin: Option<&[u8]>) -> Outcome {
    let script = format!("ulimit -v {MEMORY_CAP_KIB} && exec \"$0\" \"$@\"");
    let mut child = command_in_shell("sh", &script)
        .args(args)
        .current_dir(dir)
        .stdin(if stdin.is_some() {
            Stdio::piped()
        } else {
            Stdio::null()
        })
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("cannot start sh");
    if let Some(bytes) = stdin {
        // A refusal may close its input early: that is not this test's concern.
        let _ = child.stdin.take().unwrap().write_all(bytes);
    }
    let mut stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut text = vec![];
        std::io::Read::read_to_end(&mut stderr, &mut text).unwrap();
        text
    });
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if started.elapsed() > TIME_LIMIT {
            let _ = child.kill();
            let _ = child.wait();
            panic!("timbre {args:?} ran past {TIME_LIMIT:?}");
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let stderr = strip_ansi(&String::from_utf8_lossy(&reader.join().unwrap()));
    Outcome {
        code: status.code(),
        stderr,
        took: started.elapsed(),
    }
}

/// Checks one run: it ended by itself with 0 (for `ok`) or 1 and the expected code,
/// no panic, a bounded report, and an output file only when it rendered.
fn check(what: &str, outcome: &Outcome, expect: &str, output: &Path) {
    let Outcome { code, stderr, took } = outcome;
    let shown = &stderr[..stderr.len().min(2000)];
    assert!(
        !stderr.contains("panicked") && !stderr.contains("memory allocation"),
        "{what}: crashed\n{shown}"
    );
    assert!(
        stderr.len() <= MAX_REPORT_BYTES,
        "{what}: a report of {} bytes",
        stderr.len()
    );
    if expect == "ok" {
        assert_eq!(*code, Some(0), "{what}: did not render\n{shown}");
        assert!(output.exists(), "{what}: no output");
    } else {
        assert_eq!(*code, Some(1), "{what}: expected {expect}\n{shown}");
        assert!(
            stderr.contains(expect),
            "{what}: expected {expect}\n{shown}"
        );
        assert!(!output.exists(), "{what}: left an output behind");
    }
    eprintln!("{what}: {expect} in {:.2} s", took.as_secs_f64());
}

/// What a corpus file says it must give.
fn expectation(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    let line = text.lines().nth(1).unwrap_or_default();
    line.strip_prefix("; expect: ")
        .unwrap_or_else(|| panic!("{}: no `; expect:` line", path.display()))
        .trim()
        .to_owned()
}

fn render(dir: &Path, input: &str, output: &Path) -> Outcome {
    let _ = std::fs::remove_file(output);
    run_capped(
        dir,
        &[
            "render",
            input,
            "-o",
            output.to_str().unwrap(),
            "--quiet",
            "--threads",
            "1",
        ],
        None,
    )
}

#[test]
fn every_file_of_the_hostile_corpus_gets_its_diagnostic() {
    let dir = workspace_root().join("tests/hostile");
    let out = tempfile::tempdir().unwrap();
    let output = out.path().join("out.wav");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "tt"))
        .collect();
    files.sort();
    assert!(files.len() >= 60, "only {} files", files.len());
    for file in &files {
        let name = file.file_name().unwrap().to_str().unwrap();
        let outcome = render(&dir, name, &output);
        check(name, &outcome, &expectation(file), &output);
    }
}

/// Writes a mono 16-bit WAV of `frames` samples at `rate` (a slow ramp).
fn write_wav(path: &Path, rate: u32, frames: usize) {
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: rate,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut writer = hound::WavWriter::create(path, spec).unwrap();
    for k in 0..frames {
        writer.write_sample(((k % 1000) as i16) * 16).unwrap();
    }
    writer.finalize().unwrap();
}

#[test]
fn inputs_too_large_for_the_repository_get_their_diagnostics() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let output = d.join("out.wav");
    let write = |name: &str, bytes: &[u8]| std::fs::write(d.join(name), bytes).unwrap();

    // Lines of 10 MB: refused before parsing (the limit is 8 MiB).
    write(
        "line-10mb.tt",
        format!("(+ {})", "1 ".repeat(5_000_000)).as_bytes(),
    );
    write(
        "symbol-10mb.tt",
        format!("({} t)", "x".repeat(10_000_000)).as_bytes(),
    );
    write(
        "string-10mb.tt",
        format!("(sample \"{}\")", "a".repeat(10_000_000)).as_bytes(),
    );
    let over = "more than 8 MiB";
    for name in ["line-10mb.tt", "symbol-10mb.tt", "string-10mb.tt"] {
        let outcome = render(d, name, &output);
        check(name, &outcome, over, &output);
    }
    // Under the limit: a 7 MB line of numbers parses within the memory cap, and a
    // 4 MB name gets its diagnostic without comparing it with every node's name.
    write(
        "line-7mb.tt",
        format!("(* 1e-7 (sine (* t 440)) (+ {}))", "1 ".repeat(3_500_000)).as_bytes(),
    );
    check(
        "line-7mb.tt",
        &render(d, "line-7mb.tt", &output),
        "ok",
        &output,
    );
    write(
        "symbol-4mb.tt",
        format!("({} t)", "x".repeat(4_000_000)).as_bytes(),
    );
    let outcome = render(d, "symbol-4mb.tt", &output);
    check(
        "symbol-4mb.tt",
        &outcome,
        "timbre::unknown-function",
        &output,
    );

    // Binary junk, as a file and on standard input.
    let mut junk = vec![0u8; 1 << 20];
    let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
    for byte in &mut junk {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        *byte = x as u8;
    }
    write("junk.tt", &junk);
    check(
        "junk.tt",
        &render(d, "junk.tt", &output),
        "not UTF-8",
        &output,
    );
    let outcome = run_capped(
        d,
        &["render", "-", "-o", output.to_str().unwrap(), "--quiet"],
        Some(&junk),
    );
    check("junk on stdin", &outcome, "not UTF-8", &output);
    // Text junk: every printable character, shuffled, 2 MB.
    let printable: Vec<u8> = junk.iter().map(|b| b' ' + b % 95).collect();
    write("printable.tt", &printable[..]);
    let outcome = render(d, "printable.tt", &output);
    check("printable.tt", &outcome, "timbre::", &output);

    // 150 000 instances: past the limit of 100 000, refused while lowering.
    let mut scene = String::from("(define-sound a () (* 0.01 (sine (* t 440))))\n");
    for k in 0..150_000 {
        scene.push_str(&format!(
            "(instance i{k} (a) :start {:.3})\n",
            k as f64 * 1e-3
        ));
    }
    write("instances.tt", scene.as_bytes());
    let outcome = render(d, "instances.tt", &output);
    check(
        "instances.tt",
        &outcome,
        "timbre::too-many-instances",
        &output,
    );

    // Includes 70 deep: past the limit of 64.
    for k in 0..70 {
        write(
            &format!("chain{k}.tt"),
            format!("(include \"chain{}.tt\")\n(define x{k} {k})", k + 1).as_bytes(),
        );
    }
    write("chain70.tt", b"(define end 1)");
    write("deep.tt", b"(include \"chain0.tt\")\n(sine (* t 440))");
    let outcome = render(d, "deep.tt", &output);
    check("deep.tt", &outcome, "timbre::include-too-deep", &output);

    // Sound files whose sizes come from their headers: a 200 KB WAV at 1 Hz, as an
    // impulse response resampled to 48 kHz, would be 100 000 s; a 1200 s one on
    // 64 lanes needs 220 GiB of spectra.
    write_wav(&d.join("one-hertz.wav"), 1, 100_000);
    write("slow-ir.tt", b"(conv (sine (* t 440)) \"one-hertz.wav\")");
    let outcome = render(d, "slow-ir.tt", &output);
    check("slow-ir.tt", &outcome, "timbre::too-much-memory", &output);
    write_wav(&d.join("long.wav"), 1000, 1_200_000);
    write(
        "long-ir.tt",
        b"(combine (conv (sine (* t (iota 64))) \"long.wav\"))",
    );
    let outcome = render(d, "long-ir.tt", &output);
    check("long-ir.tt", &outcome, "timbre::too-much-memory", &output);
}

/// Named pipes where files are expected: as an include, a sampled sound, a table of
/// events, a frame and the script itself, each refused at once (an ordinary open
/// would wait for a writer forever); and as outputs, refused before rendering.
#[test]
fn named_pipes_are_refused_as_inputs_and_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let output = d.join("out.wav");
    let write = |name: &str, text: &str| std::fs::write(d.join(name), text).unwrap();
    for name in ["pipe.tt", "pipe.wav", "pipe.csv", "pipe.png"] {
        let status = Command::new("mkfifo").arg(d.join(name)).status().unwrap();
        assert!(status.success());
    }
    write("include.tt", "(include \"pipe.tt\")\n(sine (* t 440))");
    write("sample.tt", "(sample \"pipe.wav\")");
    write(
        "table.tt",
        "(define-sound ping (f) (sine (* t f)))\n(instances :csv \"pipe.csv\" :class ping :start-column \"time\")",
    );
    write(
        "frame.tt",
        "(frames v :files (\"pipe.png\"))\n(sine (* t 440))",
    );
    for name in ["include.tt", "sample.tt", "table.tt", "frame.tt", "pipe.tt"] {
        let outcome = render(d, name, &output);
        check(name, &outcome, "not a regular file", &output);
    }
    write("tone.tt", "(sine (* t 440))");
    let outcome = run_capped(
        d,
        &[
            "render",
            "tone.tt",
            "-o",
            "out.wav",
            "--spectrogram",
            "pipe.png",
            "--quiet",
        ],
        None,
    );
    check(
        "a picture onto a pipe",
        &outcome,
        "it is a named pipe",
        &output,
    );
}

/// Writes a PNG of `width × height` pixels of one grey, a row at a time (a 12000²
/// one is a few hundred kilobytes on disk and 432 MB of pixels).
fn write_flat_png(path: &Path, width: u32, height: u32) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut encoder = png::Encoder::new(file, width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_compression(png::Compression::Fast);
    let mut writer = encoder.write_header().unwrap();
    let mut stream = writer.stream_writer().unwrap();
    let row = vec![128u8; width as usize * 3];
    for _ in 0..height {
        stream.write_all(&row).unwrap();
    }
    stream.finish().unwrap();
}

#[test]
fn frames_too_large_for_the_repository_are_bounded() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let output = d.join("out.wav");
    // 12000 × 12000: kept as f64 triples it was 3.46 GB and aborted the process;
    // now refused from its header, before a pixel is decoded.
    write_flat_png(&d.join("huge.png"), 12_000, 12_000);
    assert!(std::fs::metadata(d.join("huge.png")).unwrap().len() < 4 << 20);
    std::fs::write(
        d.join("frames-huge.tt"),
        "(frames v :files (\"huge.png\"))\n(* v-1-brightness (sine (* t 440)))",
    )
    .unwrap();
    let outcome = render(d, "frames-huge.tt", &output);
    check(
        "frames-huge.tt",
        &outcome,
        "timbre::frames-too-large",
        &output,
    );
    assert!(
        outcome.stderr.contains("12000×12000") && outcome.stderr.contains("huge.png"),
        "{}",
        outcome.stderr
    );
    assert!(outcome.took < Duration::from_secs(5), "{:?}", outcome.took);
    // 4096 × 4096, the most pixels a frame may have: read, twice, within the cap.
    write_flat_png(&d.join("big.png"), 4096, 4096);
    std::fs::write(
        d.join("frames-big.tt"),
        "(scene :duration 0.5)\n(frames v :files (\"big.png\" \"big.png\") :fps 4)\n\
         (* 0.1 v-1-brightness (sine (* t 440)))",
    )
    .unwrap();
    let outcome = render(d, "frames-big.tt", &output);
    check("frames-big.tt", &outcome, "ok", &output);
}
