//! `timbre bench`: runs both engines on a workload and prints a table; rejects
//! unknown workloads. Nothing here asserts on speed.

mod common;

use common::*;

/// Whether `cell` is a number followed by `suffix`, e.g. `17.8×`.
fn is_number_with(cell: &str, suffix: &str) -> bool {
    cell.strip_suffix(suffix)
        .is_some_and(|n| n.parse::<f64>().is_ok_and(|x| x.is_finite() && x > 0.0))
}

#[test]
fn quick_bench_of_one_workload_reports_both_engines() {
    let run = run(["bench", "--quick", "bell-100"]);
    run.assert_success();
    let out = &run.stdout;
    assert!(out.starts_with("timbre bench: "), "{out}");
    assert!(out.contains("single thread"), "{out}");
    for column in [
        "interp samples/s",
        "jit samples/s",
        "jit/interp",
        "compile",
        "callbacks",
    ] {
        assert!(out.contains(column), "no `{column}` column:\n{out}");
    }
    let row: Vec<&str> = out
        .lines()
        .find(|l| l.starts_with("bell-100 "))
        .unwrap_or_else(|| panic!("no bell-100 row:\n{out}"))
        .split_whitespace()
        .collect();
    // bell-100, interp rate + prefix, jit rate + prefix, ratio, two real-time
    // factors, compile time + unit, the callbacks' share + %, the rate on every core
    // + prefix.
    assert_eq!(row.len(), 14, "{row:?}");
    assert!(row[12].parse::<f64>().is_ok(), "{row:?}");
    for rate in [row[1], row[3]] {
        assert!(rate.parse::<f64>().is_ok(), "{row:?}");
    }
    for factor in &row[5..8] {
        assert!(is_number_with(factor, "×"), "{row:?}");
    }
    assert!(row[8].parse::<f64>().is_ok() && row[9] == "ms", "{row:?}");
    let share: f64 = row[10].parse().unwrap();
    assert!((0.0..=100.0).contains(&share) && row[11] == "%", "{row:?}");
    // Only the workload asked for.
    assert!(!out.contains("swarm-50"), "{out}");
    // The compile-time table, one row per tree size.
    assert!(out.contains("compile time by tree size"), "{out}");
    for nodes in ["100", "300", "1000"] {
        assert!(
            out.lines()
                .any(|l| l.split_whitespace().next() == Some(nodes)
                    && l.contains(" ms")
                    && l.contains(" µs")),
            "no row for {nodes} nodes:\n{out}"
        );
    }
}

#[test]
fn unknown_workload_is_refused_naming_the_valid_ones() {
    let run = run(["bench", "--quick", "bell-7"]);
    run.assert_code(2);
    run.assert_stderr_has("bell-7");
    for name in timbre_benches::WORKLOADS {
        run.assert_stderr_has(name);
    }
    assert!(run.stdout.is_empty(), "{}", run.stdout);
}

#[test]
fn quick_conflicts_with_explicit_durations() {
    run(["bench", "--quick", "--seconds", "2", "bell-100"]).assert_code(2);
    run(["bench", "--seconds", "0", "bell-100"]).assert_code(2);
    run(["bench", "--runs", "0", "bell-100"]).assert_code(2);
}

/// The share of time in callbacks tells a compiled tree from one the JIT hands back
/// to the interpreter: a swarm of smooth noises and a bell's modal bank are compiled,
/// the propagation of sources in space is computed by the interpreter's kernel.
#[test]
fn the_callback_share_shows_what_is_not_compiled() {
    let run = run(["bench", "--quick", "swarm-50", "bell-100", "space-100"]);
    run.assert_success();
    let share = |name: &str| -> f64 {
        let row: Vec<&str> = run
            .stdout
            .lines()
            .find(|l| l.starts_with(&format!("{name} ")))
            .unwrap_or_else(|| panic!("no {name} row:\n{}", run.stdout))
            .split_whitespace()
            .collect();
        let percent = row.iter().position(|w| *w == "%").expect("a share in %");
        row[percent - 1].parse().unwrap()
    };
    for compiled in ["swarm-50", "bell-100"] {
        let share = share(compiled);
        assert!(share < 5.0, "{compiled}: {share} % in callbacks");
    }
    let called_back = share("space-100");
    assert!(
        called_back > 50.0,
        "space-100: {called_back} % in callbacks"
    );
}
