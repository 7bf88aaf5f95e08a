//! Tests of the checker itself, on synthetic sources and manifests: it must
//! catch the cycles and the dependencies it is there for, and only those.

use std::path::Path;

use super::graph::{Cycle, CycleScope, check_crate};
use super::layering::{Violation, check_manifest};
use super::sources::Sources;
use crate::ALLOWED_DEPENDENCIES;

/// The root file of the synthetic crates.
const LIB: &str = "demo/src/lib.rs";

/// The cycles of the synthetic crate `files` (rooted at [`LIB`]).
fn cycles(files: &[(&str, &str)]) -> Vec<String> {
    cycles_of(files, CycleScope::Everywhere)
}

/// The cycles of `scope` of the synthetic crate `files`.
fn cycles_of(files: &[(&str, &str)], scope: CycleScope) -> Vec<String> {
    let sources = Sources::from_texts(files);
    assert!(sources.errors.is_empty(), "{:?}", sources.errors);
    let (tree, _, cycles) = check_crate(Path::new(LIB), &sources, scope);
    assert!(tree.missing.is_empty(), "{:?}", tree.missing);
    cycles.iter().map(Cycle::chain).collect()
}

#[test]
fn finds_a_two_file_cycle_across_modules() {
    let found = cycles(&[
        (LIB, "mod a; mod b;"),
        ("demo/src/a.rs", "use crate::b::B; pub struct A(B);"),
        ("demo/src/b.rs", "use crate::a::A; pub struct B; fn f(_: A) {}"),
    ]);
    assert_eq!(found, ["demo/src/a.rs -> demo/src/b.rs -> demo/src/a.rs"]);
}

#[test]
fn finds_a_three_file_cycle() {
    let found = cycles(&[
        (LIB, "pub mod a; pub mod b; pub mod c;"),
        ("demo/src/a.rs", "use crate::b::B; pub struct A;"),
        ("demo/src/b.rs", "use super::c::C; pub struct B;"),
        ("demo/src/c.rs", "pub struct C; impl C { fn a() -> crate::a::A { crate::a::A } }"),
    ]);
    assert_eq!(found, ["demo/src/a.rs -> demo/src/b.rs -> demo/src/c.rs -> demo/src/a.rs"]);
}

#[test]
fn finds_a_cycle_through_a_nested_use_group() {
    let found = cycles(&[
        (LIB, "mod a; mod b; mod c;"),
        ("demo/src/a.rs", "use crate::{c::C, b::{B, helper::{self, Tool}}};"),
        ("demo/src/b.rs", "pub mod helper { pub struct Tool; } pub struct B; use crate::a::A;"),
        ("demo/src/c.rs", "pub struct C;"),
    ]);
    assert_eq!(found, ["demo/src/a.rs -> demo/src/b.rs -> demo/src/a.rs"]);
}

#[test]
fn finds_a_cycle_through_an_inline_path_in_a_function_body() {
    let found = cycles(&[
        (LIB, "mod trial; mod hw_rig;"),
        (
            "demo/src/trial.rs",
            "pub struct Spec; pub fn build() { let _ = crate::hw_rig::build_hw_rig(Spec); }",
        ),
        ("demo/src/hw_rig.rs", "use crate::trial::Spec; pub fn build_hw_rig(_: Spec) {}"),
    ]);
    assert_eq!(found, ["demo/src/hw_rig.rs -> demo/src/trial.rs -> demo/src/hw_rig.rs"]);
}

#[test]
fn finds_a_cycle_inside_one_module_unless_only_across_modules_are_asked_for() {
    let files = [
        (LIB, "pub mod study; pub mod trial;"),
        ("demo/src/study/mod.rs", "mod tables; pub use tables::Table; pub struct Config;"),
        ("demo/src/study/tables.rs", "use super::Config; pub struct Table(Config);"),
        ("demo/src/trial.rs", "use crate::study::Table;"),
    ];
    assert_eq!(
        cycles(&files),
        ["demo/src/study/mod.rs -> demo/src/study/tables.rs -> demo/src/study/mod.rs"]
    );
    assert_eq!(cycles_of(&files, CycleScope::AcrossModules), Vec::<String>::new());
    // Not for want of seeing the edges: both directions are in the graph.
    let sources = Sources::from_texts(&files);
    let (_, graph, _) = check_crate(Path::new(LIB), &sources, CycleScope::Everywhere);
    assert_eq!(
        graph.via(Path::new("demo/src/study/mod.rs"), Path::new("demo/src/study/tables.rs")),
        Some("tables::Table")
    );
    assert_eq!(
        graph.via(Path::new("demo/src/study/tables.rs"), Path::new("demo/src/study/mod.rs")),
        Some("super::Config")
    );
    assert_eq!(
        graph.via(Path::new("demo/src/trial.rs"), Path::new("demo/src/study/mod.rs")),
        Some("crate::study::Table")
    );
}

#[test]
fn ignores_the_imports_of_the_crate_root() {
    let found = cycles(&[
        (LIB, "mod a; pub use a::A; pub struct Root; fn f() { a::g() }"),
        ("demo/src/a.rs", "use crate::Root; pub struct A(Root); pub fn g() {}"),
    ]);
    assert_eq!(found, Vec::<String>::new());
}

#[test]
fn finds_cycles_through_module_aliases_and_macros() {
    let found = cycles(&[
        (LIB, "mod a; mod b; mod c;"),
        ("demo/src/a.rs", "use crate::b; pub fn f() { b::g() }"),
        ("demo/src/b.rs", "pub fn g() { println!(\"{:?}\", crate::c::h()); }"),
        ("demo/src/c.rs", "pub fn h() -> u8 { assert!(super::a::f() == ()); 0 }"),
    ]);
    assert_eq!(found, ["demo/src/a.rs -> demo/src/b.rs -> demo/src/c.rs -> demo/src/a.rs"]);
}

#[test]
fn resolves_path_attributes_inline_modules_and_nested_files() {
    let found = cycles(&[
        (LIB, "mod a; mod b; mod outer; mod other;"),
        (
            "demo/src/a.rs",
            "pub struct A; #[path = \"a_impl.rs\"] pub mod imp; #[cfg(test)] mod tests { use crate::b::B; }",
        ),
        ("demo/src/a_impl.rs", "use super::A; pub struct X;"),
        ("demo/src/b.rs", "pub struct B; use crate::a::imp::X;"),
        ("demo/src/outer.rs", "pub mod inner;"),
        ("demo/src/outer/inner.rs", "pub struct I; use crate::other::O;"),
        ("demo/src/other/mod.rs", "pub struct O(super::outer::inner::I);"),
    ]);
    assert_eq!(
        found,
        [
            "demo/src/a.rs -> demo/src/b.rs -> demo/src/a_impl.rs -> demo/src/a.rs",
            "demo/src/other/mod.rs -> demo/src/outer/inner.rs -> demo/src/other/mod.rs",
        ]
    );
}

#[test]
fn ignores_other_crates_and_local_names() {
    let found = cycles(&[
        (LIB, "mod a; mod b;"),
        ("demo/src/a.rs", "use std::fmt; use ::b::B; fn f(b: u8) -> u8 { b::MAX.min(b) }"),
        ("demo/src/b.rs", "use crate::a; pub struct B;"),
    ]);
    assert_eq!(found, Vec::<String>::new());
}

/// The violations of the synthetic manifest `text` against [`ALLOWED_DEPENDENCIES`].
fn violations(text: &str) -> Vec<Violation> {
    let manifest: toml::Table = text.parse().expect("a valid manifest");
    let workspace: toml::Table =
        "slidetrack-sim = { path = \"sim\" }\nsimulator = { path = \"sim\", package = \"slidetrack-sim\" }"
            .parse()
            .expect("valid workspace dependencies");
    check_manifest(&manifest, &workspace, ALLOWED_DEPENDENCIES)
}

#[test]
fn reports_a_forbidden_dependency() {
    let found = violations(
        "[package]\nname = \"slidetrack-render\"\n\
         [dependencies]\nslidetrack-core.workspace = true\nslidetrack-vision.workspace = true\nserde = \"1\"\n",
    );
    assert_eq!(found.len(), 1, "{found:?}");
    let message = found[0].to_string();
    assert_eq!((found[0].krate.as_str(), found[0].dependency.as_str()), ("render", "vision"));
    assert!(
        message.contains("[dependencies]") && message.contains("`render` may depend only on core"),
        "{message}"
    );
}

#[test]
fn keeps_the_simulator_in_dev_dependencies() {
    let allowed =
        "[package]\nname = \"slidetrack-control\"\n[dev-dependencies]\nslidetrack-sim.workspace = true\n";
    assert_eq!(violations(allowed), []);
    let renamed = "[package]\nname = \"slidetrack-control\"\n[dependencies]\nsimulator.workspace = true\n";
    let found = violations(renamed);
    assert_eq!(found.len(), 1, "{found:?}");
    let message = found[0].to_string();
    assert!(message.contains("`sim` belongs in [dependencies] only of experiment, elsewhere"), "{message}");
    let in_target = "[package]\nname = \"slidetrack-core\"\n[target.'cfg(unix)'.dev-dependencies]\nslidetrack-sim = \"0.1\"\n";
    assert_eq!(violations(in_target)[0].section, "[target.'cfg(unix)'.dev-dependencies]");
}

#[test]
fn reports_a_crate_missing_from_the_table() {
    let found = violations("[package]\nname = \"slidetrack-newcomer\"\n");
    assert_eq!(found.len(), 1);
    assert!(found[0].to_string().contains("needs a row"), "{}", found[0]);
}

#[test]
fn marks_edges_made_only_by_test_code() {
    let sources = Sources::from_texts(&[
        (LIB, "mod a; mod b; #[cfg(test)] mod c;"),
        (
            "demo/src/a.rs",
            "#[cfg(test)]\nmod tests {\n    use crate::b::B;\n}\n#[test]\nfn t() { crate::c::f(); }",
        ),
        (
            "demo/src/b.rs",
            "pub struct B;\n#[cfg(test)] use crate::a::A;\nfn g() -> crate::a::A { crate::a::A }",
        ),
        ("demo/src/c.rs", "pub fn f() {}"),
    ]);
    let (_, graph, _) = check_crate(Path::new(LIB), &sources, CycleScope::Everywhere);
    let edge = |from: &str, to: &str| graph.edge(Path::new(from), Path::new(to)).expect("an edge");
    let a_b = edge("demo/src/a.rs", "demo/src/b.rs");
    assert_eq!((a_b.via.as_str(), a_b.line, a_b.test_only), ("crate::b::B", 3, true));
    assert!(edge("demo/src/a.rs", "demo/src/c.rs").test_only);
    // Code outside tests makes the edge too: that is the one reported.
    let b_a = edge("demo/src/b.rs", "demo/src/a.rs");
    assert_eq!((b_a.via.as_str(), b_a.line, b_a.test_only), ("crate::a::A", 3, false));
}
