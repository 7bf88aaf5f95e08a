//! The length of functions: every `fn` with a body (free functions, methods,
//! trait methods with a default body, nested functions) and its lines, from
//! its first line (attributes and doc comments left out) to its closing brace.

use std::path::{Path, PathBuf};

use proc_macro2::Span;
use syn::visit::Visit;

/// One function of a file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FunctionLength {
    /// Its file, relative to the workspace root.
    pub file: PathBuf,
    /// Its name.
    pub name: String,
    /// The line of its signature.
    pub line: usize,
    /// Lines from its signature to its closing brace, both included.
    pub lines: usize,
}

/// Every function with a body in `syntax`, the file `file`.
pub fn functions(file: &Path, syntax: &syn::File) -> Vec<FunctionLength> {
    let mut visitor = Functions { file, found: Vec::new() };
    visitor.visit_file(syntax);
    visitor.found
}

/// Collects the functions of one file.
struct Functions<'a> {
    file: &'a Path,
    found: Vec<FunctionLength>,
}

impl Functions<'_> {
    /// Records the function `name` whose signature starts at `start` and
    /// whose body is `block`.
    fn record(&mut self, name: &syn::Ident, start: Span, block: &syn::Block) {
        let (first, last) = (start.start().line, block.brace_token.span.close().end().line);
        self.found.push(FunctionLength {
            file: self.file.to_path_buf(),
            name: name.to_string(),
            line: first,
            lines: last + 1 - first,
        });
    }
}

impl<'ast> Visit<'ast> for Functions<'_> {
    fn visit_item_fn(&mut self, f: &'ast syn::ItemFn) {
        self.record(&f.sig.ident, signature_start(&f.vis, &f.sig), &f.block);
        syn::visit::visit_item_fn(self, f);
    }

    fn visit_impl_item_fn(&mut self, f: &'ast syn::ImplItemFn) {
        self.record(&f.sig.ident, signature_start(&f.vis, &f.sig), &f.block);
        syn::visit::visit_impl_item_fn(self, f);
    }

    fn visit_trait_item_fn(&mut self, f: &'ast syn::TraitItemFn) {
        if let Some(block) = &f.default {
            self.record(&f.sig.ident, signature_start(&syn::Visibility::Inherited, &f.sig), block);
        }
        syn::visit::visit_trait_item_fn(self, f);
    }
}

/// Where a function's first line is: its visibility, else the first
/// keyword of its signature (`const`, `async`, `extern`, `fn`).
fn signature_start(vis: &syn::Visibility, sig: &syn::Signature) -> Span {
    match vis {
        syn::Visibility::Public(token) => token.span,
        syn::Visibility::Restricted(restricted) => restricted.pub_token.span,
        syn::Visibility::Inherited => {
            let keywords = [
                sig.constness.as_ref().map(|t| t.span),
                sig.asyncness.as_ref().map(|t| t.span),
                sig.abi.as_ref().map(|a| a.extern_token.span),
            ];
            keywords.into_iter().flatten().next().unwrap_or(sig.fn_token.span)
        }
    }
}
