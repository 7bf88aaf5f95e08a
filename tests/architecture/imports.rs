//! The import check over a whole workspace: every target of every package.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::PathBuf;

use super::graph::{Cycle, CycleScope, FileGraph, check_crate};
use super::sources::{Sources, Workspace};

/// What the import check found in a workspace.
#[derive(Default)]
pub struct ImportReport {
    /// Each import cycle (by its chain), with the path that makes each of
    /// its edges, e.g. `a.rs -> b.rs: crate::b::Thing`.
    pub cycles: BTreeMap<String, Vec<String>>,
    /// Files that do not parse.
    pub parse_errors: Vec<String>,
    /// `mod x;` declarations whose file is not there.
    pub missing_files: BTreeSet<String>,
    /// Source files that no target's module tree reaches.
    pub unreached_files: Vec<PathBuf>,
    /// How many crates (targets) and files were checked.
    pub crates: usize,
}

/// Runs the import check on every target of every package of `workspace`,
/// looking for the cycles of `scope_of(package name)`.
pub fn check_workspace(workspace: &Workspace, scope_of: impl Fn(&str) -> CycleScope) -> ImportReport {
    let sources = Sources::parse(&workspace.texts);
    let mut report = ImportReport { parse_errors: sources.errors.clone(), ..ImportReport::default() };
    let mut reached = BTreeSet::new();
    for package in &workspace.packages {
        let scope = scope_of(&package.name);
        for root in &package.target_roots {
            let (tree, graph, cycles) = check_crate(root, &sources, scope);
            report.crates += 1;
            reached.extend(tree.modules.iter().map(|m| m.file.clone()));
            report.missing_files.extend(tree.missing.iter().cloned());
            for cycle in &cycles {
                report.cycles.entry(cycle.chain()).or_insert_with(|| edge_details(cycle, &graph));
            }
        }
    }
    report.unreached_files = sources.files.keys().filter(|f| !reached.contains(*f)).cloned().collect();
    report
}

/// For each edge of `cycle`, the edge and the path that makes it, where.
pub fn edge_details(cycle: &Cycle, graph: &FileGraph) -> Vec<String> {
    cycle
        .files
        .windows(2)
        .map(|pair| {
            let (from, to) = (pair[0].display(), pair[1].display());
            match graph.edge(&pair[0], &pair[1]) {
                Some(edge) => {
                    let test = if edge.test_only { " (in test code only)" } else { "" };
                    format!("{from} -> {to}: `{}` at {from}:{}{test}", edge.via, edge.line)
                }
                None => format!("{from} -> {to}"),
            }
        })
        .collect()
}

impl ImportReport {
    /// The cycles as a readable list, one chain and its edges per cycle.
    pub fn describe_cycles(&self) -> String {
        let mut text = format!(
            "{} import cycle(s) (break each by moving the shared item down a layer, \
             or into a module of its own):\n",
            self.cycles.len()
        );
        for (chain, edges) in &self.cycles {
            let _ = writeln!(text, "\n  {chain}");
            for edge in edges {
                let _ = writeln!(text, "      {edge}");
            }
        }
        text
    }
}
