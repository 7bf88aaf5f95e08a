//! The paths a file writes: every `use` (nested groups flattened), every path
//! of two segments or more in its code, and the paths in macro arguments
//! (`format!("{}", crate::x::y())`), each with the module it is written in.

use proc_macro2::{Spacing, TokenStream, TokenTree};
use syn::visit::{self, Visit};
use syn::{Attribute, Item, ItemMod, ItemUse, Macro, UseTree};

use super::modules::{ModuleId, ModuleTree, ident_name, is_test_only};

/// How a path is written.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Kind {
    /// In a `use` declaration.
    Use {
        /// The name it brings into scope (`None` for a glob).
        binding: Option<String>,
    },
    /// In code (or in a macro's arguments).
    Inline,
}

/// One path written in a file.
#[derive(Debug, Clone)]
pub struct Reference {
    /// The module whose scope it is written in (an inline `mod` of the file
    /// or the file's own module).
    pub scope: ModuleId,
    /// Its segments, e.g. `["crate", "trial", "build_rig"]`; a `use`
    /// ending in `self` ends at the module, a glob at the globbed module.
    pub segments: Vec<String>,
    /// How it is written.
    pub kind: Kind,
    /// The line it is written on.
    pub line: usize,
    /// Whether it is in test code (`#[cfg(test)]`, `#[test]`).
    pub test_only: bool,
}

/// The paths written in `file`, whose own module is `module` of `tree`.
pub fn collect(tree: &ModuleTree, module: ModuleId, file: &syn::File) -> Vec<Reference> {
    let mut collector = Collector { tree, scopes: vec![module], test_depth: 0, references: Vec::new() };
    collector.visit_file(file);
    collector.references
}

/// Walks a syntax tree and records its paths.
struct Collector<'t> {
    /// The tree whose inline modules the walk enters.
    tree: &'t ModuleTree,
    /// The modules the walk is in, innermost last.
    scopes: Vec<ModuleId>,
    /// How many test-only items (`#[cfg(test)]`, `#[test]`) the walk is in.
    test_depth: usize,
    /// What was found so far.
    references: Vec<Reference>,
}

impl Collector<'_> {
    /// The module the walk is in.
    fn scope(&self) -> ModuleId {
        *self.scopes.last().expect("the walk starts in the file's module")
    }

    /// Records a path written on `line`.
    fn record(&mut self, segments: Vec<String>, kind: Kind, line: usize) {
        let scope = self.scope();
        let test_only = self.test_depth > 0 || self.tree.modules[scope].test_only;
        self.references.push(Reference { scope, segments, kind, line, test_only });
    }

    /// Records a path of code when it has two segments or more (a single
    /// segment is a local name, `self` the receiver, or an item in scope).
    fn inline(&mut self, segments: Vec<String>, line: usize) {
        if segments.len() >= 2 {
            self.record(segments, Kind::Inline, line);
        }
    }

    /// Records every path of a `use` tree, `prefix` being the segments above it.
    fn use_tree(&mut self, prefix: &mut Vec<String>, tree: &UseTree) {
        let (segments, binding, at) = match tree {
            UseTree::Path(path) => {
                prefix.push(ident_name(&path.ident));
                self.use_tree(prefix, &path.tree);
                prefix.pop();
                return;
            }
            UseTree::Group(group) => {
                for tree in &group.items {
                    self.use_tree(prefix, tree);
                }
                return;
            }
            UseTree::Name(name) => {
                let (segments, binding) = with_last(prefix, ident_name(&name.ident));
                (segments, binding, name.ident.span())
            }
            UseTree::Rename(rename) => {
                let (segments, _) = with_last(prefix, ident_name(&rename.ident));
                (segments, Some(ident_name(&rename.rename)), rename.ident.span())
            }
            UseTree::Glob(glob) => (prefix.clone(), None, glob.star_token.spans[0]),
        };
        self.record(segments, Kind::Use { binding }, at.start().line);
    }

    /// Records the paths written in a macro's tokens.
    fn tokens(&mut self, tokens: TokenStream) {
        let trees: Vec<TokenTree> = tokens.into_iter().collect();
        let mut at = 0;
        while at < trees.len() {
            match &trees[at] {
                TokenTree::Group(group) => {
                    self.tokens(group.stream());
                    at += 1;
                }
                // A path right after `::` is absolute (`::std::x`): not ours.
                TokenTree::Ident(_) if at > 0 && is_colon(&trees[at - 1]) => at += 1,
                TokenTree::Ident(ident) => {
                    let line = ident.span().start().line;
                    let (segments, next) = path_in_tokens(&trees, at);
                    self.inline(segments, line);
                    at = next;
                }
                _ => at += 1,
            }
        }
    }
}

impl<'ast> Visit<'ast> for Collector<'_> {
    fn visit_item(&mut self, item: &'ast Item) {
        let test = usize::from(is_test_only(item_attrs(item)));
        self.test_depth += test;
        visit::visit_item(self, item);
        self.test_depth -= test;
    }

    fn visit_item_mod(&mut self, item: &'ast ItemMod) {
        if item.content.is_none() {
            return;
        }
        let name = ident_name(&item.ident);
        let child = self.tree.modules[self.scope()].children.get(&name).copied();
        // A `mod` in a function body is not in the tree: stay in the scope.
        let scope = child.filter(|&id| self.tree.modules[id].inline).unwrap_or(self.scope());
        self.scopes.push(scope);
        visit::visit_item_mod(self, item);
        self.scopes.pop();
    }

    fn visit_item_use(&mut self, item: &'ast ItemUse) {
        if item.leading_colon.is_none() {
            self.use_tree(&mut Vec::new(), &item.tree);
        }
    }

    fn visit_path(&mut self, path: &'ast syn::Path) {
        if let (None, Some(first)) = (&path.leading_colon, path.segments.first()) {
            let line = first.ident.span().start().line;
            self.inline(path.segments.iter().map(|s| ident_name(&s.ident)).collect(), line);
        }
        visit::visit_path(self, path);
    }

    fn visit_macro(&mut self, mac: &'ast Macro) {
        visit::visit_macro(self, mac);
        self.tokens(mac.tokens.clone());
    }
}

/// `prefix` followed by `last`, and the name that brings into scope; a
/// trailing `self` (`use a::{self}`) names the prefix itself.
fn with_last(prefix: &[String], last: String) -> (Vec<String>, Option<String>) {
    if last == "self" {
        (prefix.to_vec(), prefix.last().cloned())
    } else {
        let mut segments = prefix.to_vec();
        segments.push(last.clone());
        (segments, Some(last))
    }
}

/// Whether a token is a `:`.
fn is_colon(tree: &TokenTree) -> bool {
    matches!(tree, TokenTree::Punct(p) if p.as_char() == ':')
}

/// The path `a::b::c` starting at identifier `trees[at]`, and the index after it.
fn path_in_tokens(trees: &[TokenTree], at: usize) -> (Vec<String>, usize) {
    let mut segments = Vec::new();
    let mut next = at;
    while let Some(TokenTree::Ident(ident)) = trees.get(next) {
        segments.push(ident_name(ident));
        next += 1;
        let joint = matches!(trees.get(next), Some(TokenTree::Punct(p)) if p.as_char() == ':' && p.spacing() == Spacing::Joint);
        let followed = trees.get(next + 1).is_some_and(is_colon)
            && matches!(trees.get(next + 2), Some(TokenTree::Ident(_)));
        if !(joint && followed) {
            break;
        }
        next += 2;
    }
    (segments, next)
}

/// The attributes of an item.
fn item_attrs(item: &Item) -> &[Attribute] {
    match item {
        Item::Const(i) => &i.attrs,
        Item::Enum(i) => &i.attrs,
        Item::ExternCrate(i) => &i.attrs,
        Item::Fn(i) => &i.attrs,
        Item::ForeignMod(i) => &i.attrs,
        Item::Impl(i) => &i.attrs,
        Item::Macro(i) => &i.attrs,
        Item::Mod(i) => &i.attrs,
        Item::Static(i) => &i.attrs,
        Item::Struct(i) => &i.attrs,
        Item::Trait(i) => &i.attrs,
        Item::TraitAlias(i) => &i.attrs,
        Item::Type(i) => &i.attrs,
        Item::Union(i) => &i.attrs,
        Item::Use(i) => &i.attrs,
        _ => &[],
    }
}
