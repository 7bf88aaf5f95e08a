//! The layering of the crates, checked on their `Cargo.toml`s against a
//! table of allowed dependencies.

use std::fmt;

/// The prefix of the slidetrack crates' package names.
const PREFIX: &str = "slidetrack-";

/// One row of the table of allowed dependencies.
pub struct Rule {
    /// The crate, by its short name (`core` for `slidetrack-core`; the root
    /// package is `slidetrack`).
    pub krate: &'static str,
    /// The slidetrack crates it may depend on, in any section.
    pub may_depend_on: &'static [&'static str],
    /// The slidetrack crates it may name in `[dev-dependencies]` only.
    pub dev_only: &'static [&'static str],
}

/// A dependency the table does not allow.
#[derive(Debug, PartialEq, Eq)]
pub struct Violation {
    /// The crate whose manifest names it (short name).
    pub krate: String,
    /// The dependency (short name).
    pub dependency: String,
    /// The manifest section that names it, e.g. `[dependencies]`.
    pub section: String,
    /// The rule it breaks, in words.
    pub rule: String,
}

impl fmt::Display for Violation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let Violation { krate, dependency, section, rule } = self;
        write!(f, "crate `{krate}` depends on `{dependency}` in {section}: {rule}")
    }
}

/// The short name of a slidetrack package (`core` for `slidetrack-core`),
/// `None` for any other package.
pub fn short_name(package: &str) -> Option<&str> {
    if package == "slidetrack" { Some(package) } else { package.strip_prefix(PREFIX) }
}

/// The dependency tables of a manifest and the section each one is:
/// `[dependencies]`, `[dev-dependencies]`, `[build-dependencies]`, also under `[target.'cfg'.*]`.
fn sections(manifest: &toml::Table) -> Vec<(String, &toml::Table)> {
    let kinds = ["dependencies", "dev-dependencies", "build-dependencies"];
    let mut found = Vec::new();
    for kind in kinds {
        if let Some(table) = manifest.get(kind).and_then(toml::Value::as_table) {
            found.push((format!("[{kind}]"), table));
        }
    }
    let targets = manifest.get("target").and_then(toml::Value::as_table).into_iter().flatten();
    for (cfg, target) in targets {
        for kind in kinds {
            if let Some(table) = target.get(kind).and_then(toml::Value::as_table) {
                found.push((format!("[target.'{cfg}'.{kind}]"), table));
            }
        }
    }
    found
}

/// The package a dependency entry names: its `package` key (also through
/// `workspace = true` in `workspace_deps`), else its key.
fn package_of<'a>(key: &'a str, entry: &'a toml::Value, workspace_deps: &'a toml::Table) -> &'a str {
    let renamed = |value: &'a toml::Value| value.get("package").and_then(toml::Value::as_str);
    let inherited = entry.get("workspace").and_then(toml::Value::as_bool) == Some(true);
    renamed(entry)
        .or_else(|| inherited.then(|| workspace_deps.get(key).and_then(renamed)).flatten())
        .unwrap_or(key)
}

/// The rule that `rule`'s crate breaks by naming `dependency`, in words;
/// `dev` when it names it in `[dev-dependencies]`.
fn rule_text(rule: &Rule, dependency: &str, dev: bool, rules: &[Rule]) -> String {
    let allowed = if rule.may_depend_on.is_empty() {
        "no slidetrack crate".to_owned()
    } else {
        rule.may_depend_on.join(", ")
    };
    let mut text = format!("`{}` may depend only on {allowed}", rule.krate);
    if !rule.dev_only.is_empty() {
        text += &format!(" (and on {} in [dev-dependencies] only)", rule.dev_only.join(", "));
    }
    // A crate that some rows take as dev-only (the simulator) has a rule of its own.
    if !dev && rules.iter().any(|r| r.dev_only.contains(&dependency)) {
        let users: Vec<&str> =
            rules.iter().filter(|r| r.may_depend_on.contains(&dependency)).map(|r| r.krate).collect();
        text += &format!(
            "; `{dependency}` belongs in [dependencies] only of {}, elsewhere at most in [dev-dependencies]",
            users.join(" and ")
        );
    }
    text
}

/// The dependencies that `manifest`, the `Cargo.toml` of a slidetrack crate,
/// names against `rules`. `workspace_deps` is `[workspace.dependencies]`.
pub fn check_manifest(
    manifest: &toml::Table,
    workspace_deps: &toml::Table,
    rules: &[Rule],
) -> Vec<Violation> {
    let package = manifest.get("package").and_then(|p| p.get("name")).and_then(toml::Value::as_str);
    let krate = package.and_then(short_name).unwrap_or(package.unwrap_or("?"));
    let Some(rule) = rules.iter().find(|r| r.krate == krate) else {
        let rule = "every slidetrack crate needs a row in the table of allowed dependencies".to_owned();
        return vec![Violation {
            krate: krate.to_owned(),
            dependency: "-".into(),
            section: "-".into(),
            rule,
        }];
    };
    let mut violations = Vec::new();
    for (section, table) in sections(manifest) {
        let dev = section.contains("dev-dependencies");
        for (key, entry) in table {
            let Some(dependency) = short_name(package_of(key, entry, workspace_deps)) else { continue };
            let allowed =
                rule.may_depend_on.contains(&dependency) || (dev && rule.dev_only.contains(&dependency));
            if !allowed {
                violations.push(Violation {
                    krate: krate.to_owned(),
                    dependency: dependency.to_owned(),
                    section: section.clone(),
                    rule: rule_text(rule, dependency, dev, rules),
                });
            }
        }
    }
    violations
}
