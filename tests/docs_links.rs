//! The README and the guides of `docs/` stay connected: every relative
//! Markdown link of `README.md` and `docs/*.md` points to a file that exists
//! and, with an anchor, to a heading of that file (GitHub's anchors); the
//! README is under 250 lines and links every page of `docs/`, so every guide
//! is reachable from it. A section moved from one page to another whose
//! links (or the links to it) were not updated fails here.
//!
//! Links in fenced code blocks and links to the web are not checked, nor
//! links that leave the repository (`../shared/...`, the workspace's
//! sibling, is not part of a clone).
#![expect(clippy::unwrap_used, reason = "test code: a failed unwrap is a failed test")]

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Component, Path, PathBuf};

/// The README may have fewer lines than this.
const README_MAX_LINES: usize = 250;

/// The repository's root.
fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The Markdown pages checked under `root`: `README.md` and `docs/*.md`,
/// as paths relative to `root`.
fn pages(root: &Path) -> Vec<PathBuf> {
    let mut pages = vec![PathBuf::from("README.md")];
    let mut docs: Vec<PathBuf> = fs::read_dir(root.join("docs"))
        .unwrap()
        .map(|entry| entry.unwrap().path())
        .filter(|path| path.extension().is_some_and(|ext| ext == "md"))
        .map(|path| path.strip_prefix(root).unwrap().to_path_buf())
        .collect();
    docs.sort();
    pages.extend(docs);
    pages
}

/// The lines of `text` outside fenced code blocks, with their numbers (from 1).
fn prose(text: &str) -> Vec<(usize, &str)> {
    let mut fenced = false;
    let mut lines = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
        } else if !fenced {
            lines.push((i + 1, line));
        }
    }
    lines
}

/// GitHub's anchor for a heading's text: lower case, spaces to `-`, every
/// other character but letters, digits, `-` and `_` dropped.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

/// The anchors of a page's headings; a repeated heading gets `-1`, `-2`, ...
/// as on GitHub.
fn anchors(text: &str) -> BTreeSet<String> {
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    let mut anchors = BTreeSet::new();
    for (_, line) in prose(text) {
        let hashes = line.chars().take_while(|&c| c == '#').count();
        if !(1..=6).contains(&hashes) || !line[hashes..].starts_with(' ') {
            continue;
        }
        let base = slug(&line[hashes..]);
        let count = seen.entry(base.clone()).or_insert(0);
        anchors.insert(if *count == 0 { base.clone() } else { format!("{base}-{count}") });
        *count += 1;
    }
    anchors
}

/// The targets of the inline links `[text](target)` of a page, with their
/// line numbers.
fn links(text: &str) -> Vec<(usize, String)> {
    let mut links = Vec::new();
    for (number, line) in prose(text) {
        let mut rest = line;
        while let Some(at) = rest.find("](") {
            rest = &rest[at + 2..];
            let end = rest.find([')', ' ']).unwrap_or(rest.len());
            links.push((number, rest[..end].to_string()));
            rest = &rest[end..];
        }
    }
    links
}

/// `path` with its `.` and `..` resolved lexically, or `None` when it leaves
/// the directory it is relative to.
fn normalise(path: &Path) -> Option<PathBuf> {
    let mut out = PathBuf::new();
    for component in path.components() {
        match component {
            Component::CurDir => {}
            Component::ParentDir => {
                if !out.pop() {
                    return None;
                }
            }
            Component::Normal(part) => out.push(part),
            Component::RootDir | Component::Prefix(_) => return None,
        }
    }
    Some(out)
}

/// What one page links to inside the repository: every relative link's
/// target file (relative to `root`) and anchor, with the line it is on.
fn local_links(root: &Path, page: &Path) -> Vec<(usize, PathBuf, Option<String>)> {
    let text = fs::read_to_string(root.join(page)).unwrap();
    let dir = page.parent().unwrap_or(Path::new(""));
    let mut out = Vec::new();
    for (line, target) in links(&text) {
        if target.contains("://") || target.starts_with("mailto:") {
            continue;
        }
        let (file, anchor) = match target.split_once('#') {
            Some((file, anchor)) => (file, Some(anchor.to_string())),
            None => (target.as_str(), None),
        };
        let resolved = if file.is_empty() { Some(page.to_path_buf()) } else { normalise(&dir.join(file)) };
        if let Some(resolved) = resolved {
            out.push((line, resolved, anchor));
        }
    }
    out
}

/// Every broken relative link of `pages` under `root`, one message each.
fn broken_links(root: &Path, pages: &[PathBuf]) -> Vec<String> {
    let mut broken = Vec::new();
    for page in pages {
        for (line, file, anchor) in local_links(root, page) {
            let at = format!("{}:{line}", page.display());
            if !root.join(&file).exists() {
                broken.push(format!("{at}: {} does not exist", file.display()));
                continue;
            }
            let Some(anchor) = anchor else { continue };
            if file.extension().is_none_or(|ext| ext != "md") {
                continue;
            }
            let text = fs::read_to_string(root.join(&file)).unwrap();
            if !anchors(&text).contains(&anchor) {
                broken.push(format!("{at}: {} has no heading #{anchor}", file.display()));
            }
        }
    }
    broken
}

/// The pages of `docs/` that the README does not link to.
fn unlinked_docs(root: &Path, pages: &[PathBuf]) -> Vec<PathBuf> {
    let linked: BTreeSet<PathBuf> =
        local_links(root, Path::new("README.md")).into_iter().map(|(_, file, _)| file).collect();
    pages.iter().filter(|page| page.starts_with("docs") && !linked.contains(*page)).cloned().collect()
}

#[test]
fn every_relative_link_of_the_readme_and_the_docs_resolves() {
    let root = root();
    let broken = broken_links(&root, &pages(&root));
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}

#[test]
fn the_readme_is_short_and_links_every_page_of_docs() {
    let root = root();
    let readme = fs::read_to_string(root.join("README.md")).unwrap();
    let lines = readme.lines().count();
    assert!(lines < README_MAX_LINES, "README.md has {lines} lines, the limit is {README_MAX_LINES}");
    let pages = pages(&root);
    assert!(pages.len() > 1, "no pages in docs/");
    let unlinked = unlinked_docs(&root, &pages);
    assert!(unlinked.is_empty(), "docs pages the README does not link: {unlinked:?}");
}

#[test]
fn anchors_follow_githubs_rules() {
    assert_eq!(slug("Robotiq grippers (`kind = \"robotiq\"`)"), "robotiq-grippers-kind--robotiq");
    assert_eq!(slug("Sliding tracking (the dEKF)"), "sliding-tracking-the-dekf");
    assert_eq!(slug("RGB-D cameras over V4L2"), "rgb-d-cameras-over-v4l2");
    assert_eq!(slug("Reading a session from Rust"), "reading-a-session-from-rust");
    let text = "# A\n## Notes\n```sh\n# not a heading\n```\n## Notes\n#not one either\n";
    assert_eq!(anchors(text), BTreeSet::from(["a".into(), "notes".into(), "notes-1".into()]));
}

/// A section moved out of the README whose links still point into the
/// README, and a page that the README does not link, are both found.
#[test]
fn a_moved_section_with_stale_links_is_caught() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    fs::create_dir(root.join("docs")).unwrap();
    fs::write(root.join("README.md"), "# Tool\n\nSee [hardware](docs/hardware.md#wiring).\n").unwrap();
    // The section moved, but its link to its old neighbour still points
    // inside the README, and the anchor the README names is not there.
    fs::write(
        root.join("docs/hardware.md"),
        "# Hardware\n\nAs in [ground truth](#ground-truth).\n\n## Bring-up\n",
    )
    .unwrap();
    fs::write(root.join("docs/ground-truth.md"), "# Ground truth\n\n```toml\nx = \"[a](missing.md)\"\n```\n")
        .unwrap();
    let pages = pages(root);
    assert_eq!(
        broken_links(root, &pages),
        [
            "README.md:3: docs/hardware.md has no heading #wiring",
            "docs/hardware.md:3: docs/hardware.md has no heading #ground-truth",
        ]
    );
    assert_eq!(unlinked_docs(root, &pages), [PathBuf::from("docs/ground-truth.md")]);

    fs::write(
        root.join("README.md"),
        "# Tool\n\n[hw](docs/hardware.md#bring-up), [gt](./docs/ground-truth.md)\n",
    )
    .unwrap();
    fs::write(
        root.join("docs/hardware.md"),
        "# Hardware\n\nAs in [ground truth](ground-truth.md).\n\n## Bring-up\n",
    )
    .unwrap();
    assert!(broken_links(root, &pages).is_empty());
    assert!(unlinked_docs(root, &pages).is_empty());
    fs::write(root.join("README.md"), "[gone](docs/moved.md)\n").unwrap();
    assert_eq!(broken_links(root, &pages), ["README.md:1: docs/moved.md does not exist"]);
}
