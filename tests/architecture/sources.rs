//! The workspace on disk: its packages, the root files of their build targets,
//! their Rust sources, and those sources parsed with `syn`.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Component, Path, PathBuf};

/// The folders of a package whose `.rs` files the check reads.
const SOURCE_DIRS: [&str; 3] = ["src", "tests", "benches"];

/// Folders never read, wherever they are.
const SKIPPED_DIRS: [&str; 2] = ["target", "fuzz"];

/// One package of the workspace.
pub struct Package {
    /// Its name in its manifest, e.g. `slidetrack-core`.
    pub name: String,
    /// Its `Cargo.toml`.
    pub manifest: toml::Table,
    /// The root file of each of its targets (lib, bins, tests, benches),
    /// relative to the workspace root.
    pub target_roots: BTreeSet<PathBuf>,
}

/// The packages of a workspace and the text of their Rust sources.
pub struct Workspace {
    /// The root package's `Cargo.toml`, with `[workspace]`.
    pub manifest: toml::Table,
    /// The root package (if the root manifest has one) and every member.
    pub packages: Vec<Package>,
    /// Every `.rs` file under `src/`, `tests/` and `benches/` of every
    /// package, by its path relative to the workspace root.
    pub texts: BTreeMap<PathBuf, String>,
}

impl Workspace {
    /// Reads the workspace whose root manifest is in `root`.
    pub fn load(root: &Path) -> Workspace {
        let manifest = read_manifest(&root.join("Cargo.toml"));
        let members = manifest
            .get("workspace")
            .and_then(|w| w.get("members"))
            .and_then(toml::Value::as_array)
            .expect("the root manifest lists [workspace] members");
        let mut dirs = Vec::new();
        if manifest.contains_key("package") {
            dirs.push(PathBuf::new());
        }
        dirs.extend(members.iter().map(|m| PathBuf::from(m.as_str().expect("a member is a path"))));
        let mut texts = BTreeMap::new();
        let packages = dirs
            .into_iter()
            .map(|dir| {
                for sub in SOURCE_DIRS {
                    read_rust_files(root, &dir.join(sub), &mut texts);
                }
                load_package(root, dir)
            })
            .collect();
        Workspace { manifest, packages, texts }
    }
}

/// Reads one package: its manifest and the roots of its targets.
fn load_package(root: &Path, dir: PathBuf) -> Package {
    let manifest = read_manifest(&root.join(&dir).join("Cargo.toml"));
    let name = manifest
        .get("package")
        .and_then(|p| p.get("name"))
        .and_then(toml::Value::as_str)
        .expect("a package has a name")
        .to_owned();
    let target_roots = target_roots(root, &dir, &manifest);
    Package { name, manifest, target_roots }
}

/// Parses the TOML file at `path`.
pub fn read_manifest(path: &Path) -> toml::Table {
    let text = fs::read_to_string(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    text.parse().unwrap_or_else(|e| panic!("cannot parse {}: {e}", path.display()))
}

/// The root files of a package's targets, found the way Cargo finds them
/// (`src/lib.rs`, `src/main.rs`, `src/bin/`, `tests/`, `benches/`) and as
/// named by `path` in `[lib]`, `[[bin]]`, `[[test]]` and `[[bench]]`.
fn target_roots(root: &Path, dir: &Path, manifest: &toml::Table) -> BTreeSet<PathBuf> {
    let mut roots = BTreeSet::new();
    for file in ["src/lib.rs", "src/main.rs"] {
        if root.join(dir).join(file).is_file() {
            roots.insert(dir.join(file));
        }
    }
    for auto in ["src/bin", "tests", "benches"] {
        let Ok(entries) = fs::read_dir(root.join(dir).join(auto)) else { continue };
        for entry in entries.flatten() {
            let path = entry.path();
            let main = path.join("main.rs");
            let found = if path.extension().is_some_and(|e| e == "rs") {
                path
            } else if main.is_file() {
                main
            } else {
                continue;
            };
            let relative = found.strip_prefix(root).expect("under the workspace root");
            roots.insert(relative.to_path_buf());
        }
    }
    let lib = manifest.get("lib").into_iter();
    let listed = ["bin", "test", "bench"].iter().filter_map(|kind| manifest.get(*kind)?.as_array());
    for target in lib.chain(listed.flatten()) {
        if let Some(path) = target.get("path").and_then(toml::Value::as_str) {
            roots.insert(normalize(&dir.join(path)));
        }
    }
    roots
}

/// Adds every `.rs` file under `root/sub` to `texts`, keyed by its path
/// relative to `root`; skips `target/` and `fuzz/`.
fn read_rust_files(root: &Path, sub: &Path, texts: &mut BTreeMap<PathBuf, String>) {
    let Ok(entries) = fs::read_dir(root.join(sub)) else { return };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let relative = sub.join(&name);
        let Ok(kind) = entry.file_type() else { continue };
        if kind.is_dir() {
            if !SKIPPED_DIRS.iter().any(|skipped| name == *skipped) {
                read_rust_files(root, &relative, texts);
            }
        } else if relative.extension().is_some_and(|e| e == "rs") {
            let text = fs::read_to_string(entry.path())
                .unwrap_or_else(|e| panic!("cannot read {}: {e}", relative.display()));
            texts.insert(relative, text);
        }
    }
}

/// Removes `.` and folds `..` in a relative path, without touching the disk.
pub fn normalize(path: &Path) -> PathBuf {
    let mut parts: Vec<Component<'_>> = Vec::new();
    for part in path.components() {
        match part {
            Component::CurDir => {}
            Component::ParentDir if matches!(parts.last(), Some(Component::Normal(_))) => {
                parts.pop();
            }
            other => parts.push(other),
        }
    }
    parts.iter().collect()
}

/// Rust sources parsed with `syn`, by path.
pub struct Sources {
    /// The syntax tree of each file that parsed.
    pub files: BTreeMap<PathBuf, syn::File>,
    /// One line for each file that did not parse.
    pub errors: Vec<String>,
}

impl Sources {
    /// Parses every file of `texts`.
    pub fn parse<'a>(texts: impl IntoIterator<Item = (&'a PathBuf, &'a String)>) -> Sources {
        let mut files = BTreeMap::new();
        let mut errors = Vec::new();
        for (path, text) in texts {
            match syn::parse_file(text) {
                Ok(file) => {
                    files.insert(path.clone(), file);
                }
                Err(e) => errors.push(format!("{}: {e}", path.display())),
            }
        }
        Sources { files, errors }
    }

    /// Parses in-memory sources given as `(path, text)` pairs (for tests).
    pub fn from_texts(texts: &[(&str, &str)]) -> Sources {
        let owned: BTreeMap<PathBuf, String> =
            texts.iter().map(|(path, text)| (PathBuf::from(path), (*text).to_owned())).collect();
        Sources::parse(&owned)
    }
}
