//! The architecture of the workspace, checked on every `cargo test`:
//!
//! 1. **No import cycle anywhere.** Every `.rs` file of `src/`,
//!    `tests/` and `benches/` of every package is parsed with `syn`; the
//!    module tree of each crate (lib, bin, test, bench) is built from its root
//!    file the way rustc resolves `mod` (`foo.rs`, `foo/mod.rs`, `#[path]`,
//!    inline `mod x { }`), and a file imports another when it names one of
//!    its items through `crate::`, `super::`, `self::` (in `use`, nested
//!    groups included, in code, in macro arguments), through a child module
//!    or through a module brought in by `use`. A path ends at the file that
//!    declares (or re-exports) the item. Any cycle of such imports fails the
//!    test, in every package, inside one module too (a parent re-exporting a
//!    child that uses the parent's items: shared items go to a sibling file
//!    both import). The crate root only declares modules, so its own imports
//!    are left out.
//! 2. **Layering.** Each crate's `Cargo.toml` names only the slidetrack crates
//!    that [`ALLOWED_DEPENDENCIES`] allows it.
//! 3. **Short functions in the CLI.** No function of the `slidetrack`
//!    binary's `src/` is longer than [`CLI_MAX_FUNCTION_LINES`]: it parses
//!    arguments, converts them to the library's options and prints, and
//!    what takes longer belongs in `experiment`.

mod architecture {
    pub mod function_length;
    pub mod graph;
    pub mod imports;
    pub mod layering;
    pub mod modules;
    pub mod references;
    pub mod sources;

    mod checker_tests;
}

use std::collections::BTreeSet;
use std::path::Path;
use std::time::Instant;

use architecture::function_length::functions;
use architecture::graph::CycleScope;
use architecture::imports::check_workspace;
use architecture::layering::{Rule, check_manifest, short_name};
use architecture::sources::{Sources, Workspace};

/// The slidetrack crates each crate may depend on.
///
/// `may depend on` holds for every section of its `Cargo.toml`; `dev only`
/// crates may appear in its `[dev-dependencies]` and nowhere else. So the
/// simulator, `sim`, is a normal dependency only of its user, `experiment`;
/// the other crates, the CLI included, test against it (`core` and `render`
/// cannot: `sim` is built on them). The CLI itself depends only on
/// `experiment` and the `core` and `session` types it prints.
#[rustfmt::skip]
pub const ALLOWED_DEPENDENCIES: &[Rule] = &[
    //   crate          may depend on                                                      dev only
    rule("core",        &[],                                                               &[]),
    rule("estimators",  &[],                                                               &["sim"]),
    rule("render",      &["core"],                                                         &[]),
    rule("control",     &["core"],                                                         &["sim"]),
    rule("sim",         &["core", "render"],                                               &[]),
    rule("session",     &["core"],                                                         &["sim"]),
    rule("drivers",     &["core"],                                                         &["sim"]),
    rule("calibration", &["core", "session", "estimators"],                                &["sim"]),
    rule("vision",      &["core", "render", "session", "estimators", "calibration"],       &["sim"]),
    rule("live",        &["core", "session"],                                              &[]),
    rule("ros2",        &["core", "session"],                                              &[]),
    rule("experiment",  &["core", "render", "sim", "session", "drivers", "estimators",
                          "control", "calibration", "vision", "live", "ros2"],             &[]),
    // The CLI parses, converts and prints: its commands go through `experiment`.
    rule("slidetrack",  &["core", "session", "experiment"],
                        &["sim", "drivers", "estimators", "vision", "live"]),
];

/// One row of [`ALLOWED_DEPENDENCIES`].
const fn rule(
    krate: &'static str,
    may_depend_on: &'static [&'static str],
    dev_only: &'static [&'static str],
) -> Rule {
    Rule { krate, may_depend_on, dev_only }
}

/// The workspace this test belongs to.
fn workspace_root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn no_import_cycles_between_modules() {
    let started = Instant::now();
    let workspace = Workspace::load(workspace_root());
    // No cycle at all, in any package, inside one module either.
    let report = check_workspace(&workspace, |_| CycleScope::Everywhere);
    eprintln!(
        "architecture: {} files, {} crates checked in {:.2?}",
        workspace.texts.len(),
        report.crates,
        started.elapsed()
    );
    for missing in &report.missing_files {
        eprintln!("note: {missing}");
    }
    for file in &report.unreached_files {
        eprintln!("note: {} is in no module tree (dead file?)", file.display());
    }
    assert!(report.parse_errors.is_empty(), "files that do not parse:\n{}", report.parse_errors.join("\n"));
    assert!(report.crates > 0 && !workspace.texts.is_empty(), "the check found no sources");
    assert!(report.cycles.is_empty(), "{}", report.describe_cycles());
}

#[test]
fn crates_respect_the_layering() {
    let workspace = Workspace::load(workspace_root());
    let workspace_deps = workspace
        .manifest
        .get("workspace")
        .and_then(|w| w.get("dependencies"))
        .and_then(toml::Value::as_table)
        .cloned()
        .unwrap_or_default();
    let violations: Vec<String> = workspace
        .packages
        .iter()
        .flat_map(|package| check_manifest(&package.manifest, &workspace_deps, ALLOWED_DEPENDENCIES))
        .map(|violation| format!("  {violation}"))
        .collect();
    let packages: BTreeSet<&str> = workspace.packages.iter().filter_map(|p| short_name(&p.name)).collect();
    let rows: BTreeSet<&str> = ALLOWED_DEPENDENCIES.iter().map(|r| r.krate).collect();
    assert_eq!(packages, rows, "the table needs one row per package of the workspace");
    assert!(violations.is_empty(), "dependencies the layering forbids:\n{}", violations.join("\n"));
}

#[test]
fn the_simulator_is_a_normal_dependency_only_of_its_users() {
    let users: Vec<&str> =
        ALLOWED_DEPENDENCIES.iter().filter(|r| r.may_depend_on.contains(&"sim")).map(|r| r.krate).collect();
    assert_eq!(users, ["experiment"]);
}

#[test]
fn the_table_is_layered() {
    // Each crate may depend only on crates of rows above it: no cycle.
    for (row, rule) in ALLOWED_DEPENDENCIES.iter().enumerate() {
        for dependency in rule.may_depend_on {
            let above = ALLOWED_DEPENDENCIES[..row].iter().any(|r| r.krate == *dependency);
            assert!(above, "`{}` may depend on `{dependency}`, which is not above it", rule.krate);
        }
    }
}

/// The longest a function of the CLI's `src/` may be, signature to closing
/// brace (lines).
pub const CLI_MAX_FUNCTION_LINES: usize = 60;

#[test]
fn cli_functions_are_short() {
    let workspace = Workspace::load(workspace_root());
    let cli_sources = workspace.texts.iter().filter(|(path, _)| path.starts_with("src"));
    let sources = Sources::parse(cli_sources);
    assert!(sources.errors.is_empty(), "files that do not parse:\n{}", sources.errors.join("\n"));
    let mut all: Vec<_> = sources.files.iter().flat_map(|(file, syntax)| functions(file, syntax)).collect();
    assert!(all.len() > 50, "the check found only {} functions in src/", all.len());
    all.sort_by_key(|f| std::cmp::Reverse(f.lines));
    let long: Vec<String> = all
        .iter()
        .take_while(|f| f.lines > CLI_MAX_FUNCTION_LINES)
        .map(|f| format!("  {}:{} `{}`: {} lines", f.file.display(), f.line, f.name, f.lines))
        .collect();
    eprintln!(
        "longest function of src/: {}:{} `{}`, {} lines",
        all[0].file.display(),
        all[0].line,
        all[0].name,
        all[0].lines
    );
    assert!(
        long.is_empty(),
        "functions of src/ over {CLI_MAX_FUNCTION_LINES} lines (move what they assemble into `experiment`):\n{}",
        long.join("\n")
    );
}
