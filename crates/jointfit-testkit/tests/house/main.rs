//! House measures of the repository, each held to a ceiling that only goes down.
//!
//! Each test measures one property of the tracked source, prints the number and what makes
//! it up, and fails when the number is above its constant below. When a change lowers a
//! number, lower its constant to match (the test says so), so that it cannot grow back.
//! `scripts/house_metrics.py` measures the same seven numbers with the Python standard
//! library; the last test checks that the two agree.

mod measures;
mod paths;
mod source;

use std::sync::OnceLock;

use source::RustFile;

/// Words that tell how the code was made rather than what it does (the list is in
/// `measures.rs`) and dates of work, in any text file of the repository. Goal: 0.
const PROCESS_WORDS: usize = 0;
/// Functions whose body spans more than 100 lines, under `crates/`. Goal: at most 10.
const LONG_FUNCTIONS: usize = 4;
/// Public items of the core library (methods and re-exported names included). Goal: at most 250.
const CORE_PUBLIC_ITEMS: usize = 250;
/// Modules of `jointfit-io` that run fits, IK or calibration. Goal: 0 (the io crate reads
/// and writes formats).
const IO_WORKFLOW_MODULES: usize = 0;
/// Lines of the shipped binary's code that reach into the source tree. Goal: 0.
const BINARY_SOURCE_TREE_PATHS: usize = 0;
/// Dependency cycles among the core's top-level modules. Goal: 0.
const CORE_MODULES_IN_CYCLES: usize = 0;
/// Phrases of work history (commit hashes, "this branch", machine load, "revision N", ...)
/// in `docs/` and `README.md`, which describe the method and the current behaviour (the
/// ones left are in `docs/memory.md`, `docs/stopping.md` and `docs/streaming.md`). Goal: 0.
const HISTORY_PHRASES: usize = 0;

fn files() -> &'static [RustFile] {
    static FILES: OnceLock<Vec<RustFile>> = OnceLock::new();
    FILES.get_or_init(|| source::rust_files(&source::root()))
}

/// Prints `findings` under `title` and checks their number against `ceiling`.
fn ratchet(title: &str, findings: &[String], ceiling: usize) {
    println!("{title}: {} (ceiling {ceiling})", findings.len());
    for finding in findings {
        println!("  {finding}");
    }
    assert!(
        findings.len() <= ceiling,
        "{title}: {} is above the ceiling {ceiling}",
        findings.len()
    );
    if findings.len() < ceiling {
        println!(
            "{title}: lower the ceiling in this file to {}",
            findings.len()
        );
    }
}

#[test]
fn no_process_words_in_tracked_files() {
    ratchet(
        "process words",
        &measures::process_words(&source::root()),
        PROCESS_WORDS,
    );
}

#[test]
fn long_functions_stay_few() {
    ratchet(
        "functions over 100 lines",
        &measures::long_functions(files()),
        LONG_FUNCTIONS,
    );
}

#[test]
fn core_public_surface_stays_small() {
    ratchet(
        "core public items",
        &measures::core_public_items(files()),
        CORE_PUBLIC_ITEMS,
    );
}

#[test]
fn io_crate_holds_no_workflow() {
    ratchet(
        "io modules that run workflows",
        &measures::io_workflow(files()),
        IO_WORKFLOW_MODULES,
    );
}

#[test]
fn binary_does_not_reach_into_the_source_tree() {
    let found = measures::binary_source_paths(&source::root(), files());
    ratchet(
        "source-tree paths in the binary",
        &found,
        BINARY_SOURCE_TREE_PATHS,
    );
}

#[test]
fn core_top_level_modules_form_no_cycles() {
    let (in_cycles, cycles) = measures::core_cycles(files());
    println!("core modules in cycles: {in_cycles}");
    ratchet("core dependency cycles", &cycles, CORE_MODULES_IN_CYCLES);
    assert_eq!(cycles.is_empty(), in_cycles == 0, "{cycles:?}");
}

#[test]
fn docs_tell_no_work_history() {
    ratchet(
        "history phrases in the docs",
        &measures::history_phrases(&source::root()),
        HISTORY_PHRASES,
    );
}

/// The Python twin of these measures (`scripts/house_metrics.py`, standard library only)
/// finds the same seven numbers.
#[test]
fn python_twin_measures_the_same_numbers() {
    let Some(python) = jointfit_testkit::python() else {
        return;
    };
    let twin = jointfit_testkit::script::Script::new(&python, "house_metrics.py")
        .args(&["--json"])
        .run_json();
    let root = source::root();
    let ours = [
        ("process_words", measures::process_words(&root).len()),
        ("long_functions", measures::long_functions(files()).len()),
        (
            "core_public_items",
            measures::core_public_items(files()).len(),
        ),
        ("io_workflow_modules", measures::io_workflow(files()).len()),
        (
            "binary_source_tree_paths",
            measures::binary_source_paths(&root, files()).len(),
        ),
        ("core_modules_in_cycles", measures::core_cycles(files()).0),
        ("history_phrases", measures::history_phrases(&root).len()),
    ];
    for (name, count) in ours {
        assert_eq!(
            twin[name].as_u64(),
            Some(count as u64),
            "{name}: the Python twin says {}",
            twin[name]
        );
    }
}
