//! The file-level import graph of one crate, and the import cycles in it
//! (all of them, or those that cross from one top-level module to another).

use std::collections::btree_map::Entry;
use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::path::{Path, PathBuf};

use super::modules::{ModuleId, ModuleTree};
use super::references::{self, Kind, Reference};
use super::sources::Sources;

/// Rounds of `use` resolution: enough for `use` chains through aliases.
const ALIAS_ROUNDS: usize = 8;

/// Which file names an item of which other file, in one crate.
pub struct FileGraph {
    /// The top-level module of each file of the crate.
    pub module_of: BTreeMap<PathBuf, String>,
    /// Each edge `(from, to)` and where it comes from.
    pub edges: BTreeMap<(PathBuf, PathBuf), Edge>,
}

/// Where an edge of the graph comes from: the first path that makes it
/// outside test code, or in test code when there is no other.
pub struct Edge {
    /// The path, e.g. `crate::trial::build_rig`.
    pub via: String,
    /// The line of the importing file where it is written.
    pub line: usize,
    /// Whether every path making the edge is in test code.
    pub test_only: bool,
}

/// Which import cycles a check looks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CycleScope {
    /// Every cycle, inside one top-level module too.
    Everywhere,
    /// Only cycles with an edge between two top-level modules.
    AcrossModules,
}

/// An import cycle: files, the first one repeated at the end.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub struct Cycle {
    /// The chain of files, e.g. `[trial.rs, hw_rig.rs, trial.rs]`.
    pub files: Vec<PathBuf>,
}

impl FileGraph {
    /// The graph of the crate whose modules are `tree`. Edges out of the
    /// crate root file are left out: it only declares and re-exports modules.
    pub fn build(tree: &ModuleTree, sources: &Sources) -> FileGraph {
        let mut module_of = BTreeMap::new();
        let mut written = Vec::new();
        for (file, module) in tree.file_modules() {
            module_of.insert(file.to_path_buf(), tree.top_level(module).to_owned());
            if let Some(syntax) = sources.files.get(file) {
                written.extend(references::collect(tree, module, syntax));
            }
        }
        let resolver = Resolver::new(tree, &written);
        let mut edges = BTreeMap::new();
        for reference in &written {
            let Some((target, _)) = resolver.resolve(reference.scope, &reference.segments) else { continue };
            let from = &tree.modules[reference.scope].file;
            let to = &tree.modules[target].file;
            if from == to || *from == tree.root_file {
                continue;
            }
            let edge = Edge {
                via: reference.segments.join("::"),
                line: reference.line,
                test_only: reference.test_only,
            };
            match edges.entry((from.clone(), to.clone())) {
                Entry::Vacant(vacant) => {
                    vacant.insert(edge);
                }
                Entry::Occupied(mut seen) if seen.get().test_only && !edge.test_only => {
                    seen.insert(edge);
                }
                Entry::Occupied(_) => {}
            }
        }
        FileGraph { module_of, edges }
    }

    /// The files that `file` names items of.
    fn successors(&self, file: &Path) -> impl Iterator<Item = &PathBuf> {
        let start = (file.to_path_buf(), PathBuf::new());
        self.edges
            .range(start..)
            .map(|((from, to), _)| (from, to))
            .take_while(move |(from, _)| *from == file)
            .map(|(_, to)| to)
    }

    /// A shortest chain of edges from `start` to `goal`, both included.
    fn shortest_path(&self, start: &Path, goal: &Path) -> Option<Vec<PathBuf>> {
        let mut came_from: BTreeMap<&Path, &Path> = BTreeMap::new();
        let mut queue = VecDeque::from([start]);
        while let Some(file) = queue.pop_front() {
            if file == goal {
                let mut chain = vec![goal.to_path_buf()];
                let mut at = goal;
                while at != start {
                    at = came_from[at];
                    chain.push(at.to_path_buf());
                }
                chain.reverse();
                return Some(chain);
            }
            for next in self.successors(file) {
                if next != start && !came_from.contains_key(next.as_path()) {
                    came_from.insert(next, file);
                    queue.push_back(next);
                }
            }
        }
        None
    }

    /// The import cycles: for each edge that lies on a cycle, the shortest
    /// such cycle, each listed once. With [`CycleScope::AcrossModules`],
    /// only the edges between files of two different top-level modules count
    /// (a cycle inside one module, `study/mod.rs <-> study/tables.rs`, is
    /// left out).
    pub fn cycles(&self, scope: CycleScope) -> BTreeSet<Cycle> {
        let mut cycles = BTreeSet::new();
        for (from, to) in self.edges.keys() {
            if scope == CycleScope::AcrossModules && self.module_of.get(from) == self.module_of.get(to) {
                continue;
            }
            if let Some(back) = self.shortest_path(to, from) {
                let mut files = vec![from.clone()];
                files.extend(back);
                cycles.insert(Cycle::rotated(files));
            }
        }
        cycles
    }

    /// Edge `from -> to`, if there is one.
    pub fn edge(&self, from: &Path, to: &Path) -> Option<&Edge> {
        self.edges.get(&(from.to_path_buf(), to.to_path_buf()))
    }

    /// The path that makes edge `from -> to`, if there is one.
    pub fn via(&self, from: &Path, to: &Path) -> Option<&str> {
        self.edge(from, to).map(|edge| edge.via.as_str())
    }
}

impl Cycle {
    /// The cycle `files` (first repeated last) started at its smallest file,
    /// so that the same cycle found from two edges compares equal.
    fn rotated(mut files: Vec<PathBuf>) -> Cycle {
        files.pop();
        let smallest = files.iter().enumerate().min_by_key(|(_, f)| *f).map_or(0, |(i, _)| i);
        files.rotate_left(smallest);
        files.push(files[0].clone());
        Cycle { files }
    }

    /// The chain written `a.rs -> b.rs -> a.rs`.
    pub fn chain(&self) -> String {
        self.files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>().join(" -> ")
    }
}

/// Resolves paths to modules, knowing which modules each scope's `use`
/// declarations bring in under which names.
struct Resolver<'t> {
    /// The crate's modules.
    tree: &'t ModuleTree,
    /// Per scope, the modules that `use` brings in by name (`use crate::study;`).
    aliases: BTreeMap<ModuleId, BTreeMap<String, ModuleId>>,
    /// Per scope, the modules whose names a glob `use` brings in.
    globs: BTreeMap<ModuleId, BTreeSet<ModuleId>>,
}

impl<'t> Resolver<'t> {
    /// A resolver for `tree` that knows the modules that `written` imports.
    fn new(tree: &'t ModuleTree, written: &[Reference]) -> Resolver<'t> {
        let mut resolver = Resolver { tree, aliases: BTreeMap::new(), globs: BTreeMap::new() };
        for _ in 0..ALIAS_ROUNDS {
            let mut changed = false;
            for reference in written {
                let Kind::Use { binding } = &reference.kind else { continue };
                let Some((module, true)) = resolver.resolve(reference.scope, &reference.segments) else {
                    continue;
                };
                changed |= match binding {
                    Some(name) => {
                        let names = resolver.aliases.entry(reference.scope).or_default();
                        names.insert(name.clone(), module) != Some(module)
                    }
                    None => resolver.globs.entry(reference.scope).or_default().insert(module),
                };
            }
            if !changed {
                break;
            }
        }
        resolver
    }

    /// The module in which `name`, the first segment of a path written in
    /// `scope`, starts the path, if it names one of the crate's modules.
    fn start(&self, scope: ModuleId, name: &str) -> Option<ModuleId> {
        let own = |module: ModuleId| {
            let children = &self.tree.modules[module].children;
            children.get(name).or_else(|| self.aliases.get(&module)?.get(name)).copied()
        };
        match name {
            "crate" => Some(0),
            "self" => Some(scope),
            "super" => self.tree.modules[scope].parent,
            _ => own(scope).or_else(|| self.globs.get(&scope)?.iter().find_map(|&glob| own(glob))),
        }
    }

    /// The module whose file declares (or re-exports) what `segments`,
    /// written in `scope`, name, and whether the whole path names a module.
    /// `None` for paths outside the crate (other crates, local names).
    fn resolve(&self, scope: ModuleId, segments: &[String]) -> Option<(ModuleId, bool)> {
        let (first, rest) = segments.split_first()?;
        let mut module = self.start(scope, first)?;
        let mut rest = rest.iter().peekable();
        while let Some(segment) = rest.peek() {
            let next = match segment.as_str() {
                "super" => self.tree.modules[module].parent,
                name => self.tree.modules[module].children.get(name).copied(),
            };
            let Some(next) = next else { break };
            module = next;
            rest.next();
        }
        Some((module, rest.peek().is_none()))
    }
}

/// The cycles (of `scope`) of the crate whose root file is `root_file`,
/// with the graph they were found in.
pub fn check_crate(
    root_file: &Path,
    sources: &Sources,
    scope: CycleScope,
) -> (ModuleTree, FileGraph, BTreeSet<Cycle>) {
    let tree = ModuleTree::build(root_file, sources);
    let graph = FileGraph::build(&tree, sources);
    let cycles = graph.cycles(scope);
    (tree, graph, cycles)
}
