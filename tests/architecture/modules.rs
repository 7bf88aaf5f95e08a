//! The module tree of one crate, built from its root file by following
//! `mod` declarations the way rustc does: `foo.rs` or `foo/mod.rs`,
//! `#[path = "..."]`, and inline `mod x { ... }` blocks, which belong to the
//! file they are written in.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use syn::punctuated::Punctuated;
use syn::{Attribute, Expr, ExprLit, Item, ItemMod, Lit, Meta, Token};

use super::sources::{Sources, normalize};

/// Index of a module in [`ModuleTree::modules`]; the crate root is `0`.
pub type ModuleId = usize;

/// The name under which the crate root file is its own module.
pub const ROOT_MODULE: &str = "<root>";

/// One module of a crate.
pub struct Module {
    /// Its path from the crate root: empty for the root, `["study", "tables"]`
    /// for `crate::study::tables`.
    pub path: Vec<String>,
    /// The file it is written in.
    pub file: PathBuf,
    /// Whether it is an inline `mod x { ... }` block of `file`.
    pub inline: bool,
    /// Whether it is compiled for tests only (`#[cfg(test)]`, also on an ancestor).
    pub test_only: bool,
    /// The module that declares it (`None` for the root).
    pub parent: Option<ModuleId>,
    /// Its child modules by name.
    pub children: BTreeMap<String, ModuleId>,
}

/// All modules of one crate.
pub struct ModuleTree {
    /// The crate root file (`lib.rs`, `main.rs`, a test or a bench).
    pub root_file: PathBuf,
    /// The modules; `modules[0]` is the root.
    pub modules: Vec<Module>,
    /// One line for each `mod x;` whose file is not among the sources.
    pub missing: Vec<String>,
}

/// Where the `mod` declarations of one scope look for files.
struct Dirs {
    /// Where `mod x;` finds `x.rs` and `x/mod.rs`.
    children: PathBuf,
    /// What `#[path = "..."]` is relative to.
    path_attr_base: PathBuf,
}

impl ModuleTree {
    /// Builds the module tree of the crate whose root file is `root_file`.
    pub fn build(root_file: &Path, sources: &Sources) -> ModuleTree {
        let root = Module {
            path: Vec::new(),
            file: root_file.to_path_buf(),
            inline: false,
            test_only: false,
            parent: None,
            children: BTreeMap::new(),
        };
        let mut tree =
            ModuleTree { root_file: root_file.to_path_buf(), modules: vec![root], missing: Vec::new() };
        if let Some(file) = sources.files.get(root_file) {
            let dir = root_file.parent().unwrap_or(Path::new("")).to_path_buf();
            let dirs = Dirs { children: dir.clone(), path_attr_base: dir };
            let mut including = BTreeSet::from([root_file.to_path_buf()]);
            tree.add_items(0, &file.items, &dirs, sources, &mut including);
        }
        tree
    }

    /// Adds the modules that `items`, the items of module `parent`, declare.
    /// `including` holds the files being read, against `#[path]` loops.
    fn add_items(
        &mut self,
        parent: ModuleId,
        items: &[Item],
        dirs: &Dirs,
        sources: &Sources,
        including: &mut BTreeSet<PathBuf>,
    ) {
        for item in items {
            if let Item::Mod(declaration) = item {
                self.add_module(parent, declaration, dirs, sources, including);
            }
        }
    }

    /// Adds the module that `declaration` declares in `parent`, and its own children.
    fn add_module(
        &mut self,
        parent: ModuleId,
        declaration: &ItemMod,
        dirs: &Dirs,
        sources: &Sources,
        including: &mut BTreeSet<PathBuf>,
    ) {
        let name = ident_name(&declaration.ident);
        let path_attr = path_attribute(&declaration.attrs);
        if let Some((_, items)) = &declaration.content {
            let dir = match &path_attr {
                Some(path) => normalize(&dirs.path_attr_base.join(path)),
                None => dirs.children.join(&name),
            };
            let inner = Dirs { children: dir.clone(), path_attr_base: dir };
            let file = self.modules[parent].file.clone();
            let id = self.push(parent, declaration, file, true);
            self.add_items(id, items, &inner, sources, including);
            return;
        }
        let candidates = match &path_attr {
            Some(path) => vec![normalize(&dirs.path_attr_base.join(path))],
            None => vec![dirs.children.join(format!("{name}.rs")), dirs.children.join(&name).join("mod.rs")],
        };
        let Some((path, file)) = candidates.iter().find_map(|c| Some((c, sources.files.get(c)?))) else {
            let at = self.modules[parent].file.display();
            self.missing.push(format!("{at}: `mod {name};` has no file among {candidates:?}"));
            return;
        };
        let id = self.push(parent, declaration, path.clone(), false);
        if !including.insert(path.clone()) {
            return;
        }
        let dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
        // rustc treats files named by `#[path]` like `mod.rs` files.
        let mod_rs = path_attr.is_some() || path.file_name().is_some_and(|n| n == "mod.rs");
        let children = if mod_rs { dir.clone() } else { dir.join(&name) };
        let inner = Dirs { children, path_attr_base: dir };
        self.add_items(id, &file.items, &inner, sources, including);
        including.remove(path);
    }

    /// Appends the module that `declaration` declares in `parent`, written in `file`.
    fn push(&mut self, parent: ModuleId, declaration: &ItemMod, file: PathBuf, inline: bool) -> ModuleId {
        let id = self.modules.len();
        let name = ident_name(&declaration.ident);
        let mut path = self.modules[parent].path.clone();
        path.push(name.clone());
        let test_only = self.modules[parent].test_only || is_test_only(&declaration.attrs);
        let children = BTreeMap::new();
        self.modules.push(Module { path, file, inline, test_only, parent: Some(parent), children });
        self.modules[parent].children.insert(name, id);
        id
    }

    /// The module that file `file` is (the first one, if included twice).
    pub fn file_modules(&self) -> BTreeMap<&Path, ModuleId> {
        let mut files = BTreeMap::new();
        for (id, module) in self.modules.iter().enumerate().filter(|(_, m)| !m.inline) {
            files.entry(module.file.as_path()).or_insert(id);
        }
        files
    }

    /// The top-level module that module `id` belongs to: the first segment of
    /// its path, or [`ROOT_MODULE`] for the crate root.
    pub fn top_level(&self, id: ModuleId) -> &str {
        self.modules[id].path.first().map_or(ROOT_MODULE, String::as_str)
    }
}

/// The name of an identifier without its `r#` prefix.
pub fn ident_name(ident: &syn::Ident) -> String {
    let name = ident.to_string();
    name.strip_prefix("r#").map_or_else(|| name.clone(), str::to_owned)
}

/// The value of a `#[path = "..."]` attribute, if there is one.
fn path_attribute(attrs: &[Attribute]) -> Option<String> {
    attrs.iter().find_map(|attr| match &attr.meta {
        Meta::NameValue(nv) if nv.path.is_ident("path") => match &nv.value {
            Expr::Lit(ExprLit { lit: Lit::Str(s), .. }) => Some(s.value()),
            _ => None,
        },
        _ => None,
    })
}

/// Whether `attrs` make an item test code: `#[test]`, `#[cfg(test)]` or
/// `#[cfg(all(test, ...))]`.
pub fn is_test_only(attrs: &[Attribute]) -> bool {
    attrs.iter().any(|attr| {
        if attr.path().is_ident("test") {
            return true;
        }
        let Meta::List(list) = &attr.meta else { return false };
        if !list.path.is_ident("cfg") {
            return false;
        }
        match list.parse_args::<Meta>() {
            Ok(Meta::Path(path)) => path.is_ident("test"),
            Ok(Meta::List(all)) if all.path.is_ident("all") => all
                .parse_args_with(Punctuated::<Meta, Token![,]>::parse_terminated)
                .is_ok_and(|terms| terms.iter().any(|term| term.path().is_ident("test"))),
            _ => false,
        }
    })
}
