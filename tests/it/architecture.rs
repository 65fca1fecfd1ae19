//! The module import graph reads top to bottom and has no circles.
//!
//! Reads every `src/**/*.rs`, builds the graph of imports between modules
//! (one node per file: `search/pipeline`, `mesh/stl`, `cli/search`; a
//! `mod.rs` or `lib.rs`/`main.rs` is its directory's module) from the paths
//! that start with `crate::`, `super::`, `self::`, `layout_opt::` (in the
//! binary), `layout_opt_solvers::`, or a child module's name in a `use`,
//! and checks against docs/architecture.md:
//! - every module has a layer there (its own line, or the line of the
//!   nearest enclosing module that has one), and every module named there
//!   exists;
//! - no module imports a module of a higher layer;
//! - no circle: no two modules reach each other along imports. A module and
//!   its own ancestors are exempt from the circle check (a child reaching
//!   its parent's shared items, the parent re-exporting or dispatching to
//!   its children, is how Rust modules are built), but not from the layer
//!   check.
//!
//! The solver crate (crates/solvers/, `layout_opt_solvers`) is one node,
//! `layout_opt_solvers`, on a floor below every floor of the tool: any
//! module may import it, and it imports nothing of the tool (cargo sees to
//! that). An import of it by a `layout_opt_solvers::` path, or through the
//! re-exports of src/lib.rs (`crate::pnp::Solver`, `layout_opt::pose::Pose`)
//! or src/camera.rs (`crate::camera::Camera`), is an edge to that node. The
//! solver crate's own `crates/solvers/src/**/*.rs` are checked the same way
//! against the floors and table of the section "The solver crate" of
//! docs/architecture.md.
//!
//! A path through a `pub use` re-export is followed to the module that
//! defines the item, so `crate::search::SearchOutcome` counts as an import
//! of the module the search facade re-exports it from. Code under
//! `#[cfg(test)]` is left out: tests may import anything. Comments and
//! string literals are skipped, so a doc link is not an import.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The crate's own source tree.
fn source_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

/// The solver crate's source tree.
fn solver_source_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("crates/solvers/src")
}

/// The solver crate's name in paths, and its node in the tool's graph.
const SOLVER_CRATE: &str = "layout_opt_solvers";

/// The heading of the section of docs/architecture.md that describes the
/// solver crate; the floors and table above it are the tool's.
const SOLVER_SECTION: &str = "## The solver crate";

/// The layer document.
fn layer_doc() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/architecture.md")
}

#[derive(Debug, Clone, PartialEq)]
enum Token {
    Ident(String),
    PathSep,
    Punct(char),
}

/// Whether `chars[i..]` starts a prefixed string literal: `b"`, `c"`,
/// `r"`, `br"`, or a raw string with hashes (`r#"`, `br##"`), but not a
/// raw identifier (`r#type`).
fn string_prefix(chars: &[char], i: usize) -> bool {
    let at = |k: usize| chars.get(k).copied().unwrap_or('\0');
    let mut j = i;
    if at(j) == 'b' || at(j) == 'c' {
        j += 1;
        if at(j) == '"' {
            return true;
        }
    }
    if at(j) != 'r' {
        return false;
    }
    j += 1;
    while at(j) == '#' {
        j += 1;
    }
    at(j) == '"'
}

/// Tokens with their line numbers; comments, strings and char literals
/// dropped.
fn tokenize(text: &str) -> Vec<(Token, usize)> {
    let chars: Vec<char> = text.chars().collect();
    let mut tokens = Vec::new();
    let mut i = 0;
    let mut line = 1;
    let at = |i: usize| chars.get(i).copied().unwrap_or('\0');
    while i < chars.len() {
        let c = chars[i];
        if c == '\n' {
            line += 1;
            i += 1;
        } else if c.is_whitespace() {
            i += 1;
        } else if c == '/' && at(i + 1) == '/' {
            while i < chars.len() && chars[i] != '\n' {
                i += 1;
            }
        } else if c == '/' && at(i + 1) == '*' {
            let mut depth = 0;
            while i < chars.len() {
                if chars[i] == '/' && at(i + 1) == '*' {
                    depth += 1;
                    i += 2;
                } else if chars[i] == '*' && at(i + 1) == '/' {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    if chars[i] == '\n' {
                        line += 1;
                    }
                    i += 1;
                }
            }
        } else if c == '"' || string_prefix(&chars, i) {
            // A string literal: plain, byte, C, or raw with any number of #.
            let mut j = i;
            let mut raw = false;
            while chars[j] != '"' && chars[j] != '#' {
                raw |= chars[j] == 'r';
                j += 1;
            }
            let mut hashes = 0;
            while chars[j] == '#' {
                hashes += 1;
                j += 1;
            }
            j += 1; // opening quote
            loop {
                if j >= chars.len() {
                    break;
                }
                let d = chars[j];
                if d == '\n' {
                    line += 1;
                }
                if !raw && d == '\\' {
                    if at(j + 1) == '\n' {
                        line += 1;
                    }
                    j += 2;
                    continue;
                }
                if d == '"' && (0..hashes).all(|k| at(j + 1 + k) == '#') {
                    j += 1 + hashes;
                    break;
                }
                j += 1;
            }
            i = j;
        } else if c == '\'' {
            // A char literal, or a lifetime (no closing quote).
            if at(i + 1) == '\\' {
                let mut j = i + 2;
                while j < chars.len() && chars[j] != '\'' {
                    j += 1;
                }
                i = j + 1;
            } else if at(i + 2) == '\'' {
                i += 3;
            } else {
                i += 1;
            }
        } else if c.is_alphanumeric() || c == '_' {
            let start = i;
            while i < chars.len() && (chars[i].is_alphanumeric() || chars[i] == '_') {
                i += 1;
            }
            let word: String = chars[start..i].iter().collect();
            // `r#name` is the identifier `name`.
            tokens.push((Token::Ident(word), line));
        } else if c == ':' && at(i + 1) == ':' {
            tokens.push((Token::PathSep, line));
            i += 2;
        } else {
            tokens.push((Token::Punct(c), line));
            i += 1;
        }
    }
    tokens
}

/// Drops every item marked `#[cfg(test)]`, and returns the names of the
/// out-of-line modules (`mod name;`) so marked.
fn strip_test_code(tokens: Vec<(Token, usize)>) -> (Vec<(Token, usize)>, BTreeSet<String>) {
    let ident = |t: &Token, s: &str| matches!(t, Token::Ident(w) if w == s);
    let punct = |t: &Token, c: char| *t == Token::Punct(c);
    let mut kept = Vec::new();
    let mut test_modules = BTreeSet::new();
    let mut i = 0;
    while i < tokens.len() {
        let is_cfg_test = i + 6 < tokens.len()
            && punct(&tokens[i].0, '#')
            && punct(&tokens[i + 1].0, '[')
            && ident(&tokens[i + 2].0, "cfg")
            && punct(&tokens[i + 3].0, '(')
            && ident(&tokens[i + 4].0, "test")
            && punct(&tokens[i + 5].0, ')')
            && punct(&tokens[i + 6].0, ']');
        if !is_cfg_test {
            kept.push(tokens[i].clone());
            i += 1;
            continue;
        }
        i += 7;
        // Skip the item: to a `;` or `,` at its own depth, or to the end
        // of its first braced block, or to a bracket that closes around it.
        let mut depth = 0i32;
        let mut previous_ident: Option<String> = None;
        let mut saw_mod = false;
        while i < tokens.len() {
            let token = &tokens[i].0;
            match token {
                Token::Punct('(') | Token::Punct('[') | Token::Punct('{') => depth += 1,
                Token::Punct(')') | Token::Punct(']') | Token::Punct('}') => {
                    if depth == 0 {
                        break;
                    }
                    depth -= 1;
                    if depth == 0 && *token == Token::Punct('}') {
                        i += 1;
                        break;
                    }
                }
                Token::Punct(';') | Token::Punct(',') if depth == 0 => {
                    if saw_mod && *token == Token::Punct(';') {
                        if let Some(name) = previous_ident.take() {
                            test_modules.insert(name);
                        }
                    }
                    i += 1;
                    break;
                }
                Token::Ident(word) if depth == 0 => {
                    saw_mod |= word == "mod";
                    previous_ident = Some(word.clone());
                }
                _ => {}
            }
            i += 1;
        }
    }
    (kept, test_modules)
}

/// Which crate a module lives in: the library (`crate::` in src/lib.rs and
/// its modules), the binary (src/main.rs and src/cli/), or the solver crate
/// (crates/solvers/src, `layout_opt_solvers::`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Crate {
    Library,
    Binary,
    Solvers,
}

/// An absolute module path: its crate and segments.
type AbsPath = (Crate, Vec<String>);

/// One source file: its module path and its non-test tokens.
struct SourceFile {
    relative: String,
    module: AbsPath,
    tokens: Vec<(Token, usize)>,
}

/// The graph key of a file module: `search/pipeline`; `main` for the
/// binary's root; `` for the library's root; [`SOLVER_CRATE`] for the
/// solver crate's root, which is what every path into the solver crate
/// resolves to in the tool's graph (none of its files is known there).
fn key(module: &AbsPath) -> String {
    match (module.0, module.1.is_empty()) {
        (Crate::Binary, true) => "main".to_string(),
        (Crate::Solvers, true) => SOLVER_CRATE.to_string(),
        _ => module.1.join("/"),
    }
}

fn collect_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", dir.display()))
        .map(|e| e.expect("directory entry").path())
        .collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            collect_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Every non-test source file of the library and the binary (`library` is
/// [`Crate::Library`], under src/), or of the solver crate (`library` is
/// [`Crate::Solvers`], under crates/solvers/src/).
fn read_sources(library: Crate) -> Vec<SourceFile> {
    let (root, shown) = match library {
        Crate::Solvers => (solver_source_root(), "crates/solvers/src"),
        _ => (source_root(), "src"),
    };
    let mut paths = Vec::new();
    collect_files(&root, &mut paths);
    let mut files = Vec::new();
    let mut test_only: BTreeSet<AbsPath> = BTreeSet::new();
    for path in &paths {
        let relative = path
            .strip_prefix(&root)
            .expect("under src")
            .to_string_lossy()
            .replace('\\', "/");
        let stem = relative.trim_end_matches(".rs");
        let mut segments: Vec<String> = stem.split('/').map(str::to_string).collect();
        if segments.last().is_some_and(|s| s == "mod") {
            segments.pop();
        }
        let module = match segments.as_slice() {
            [only] if only == "lib" => (library, Vec::new()),
            _ if library == Crate::Solvers => (library, segments),
            [only] if only == "main" => (Crate::Binary, Vec::new()),
            [first, ..] if first == "cli" => (Crate::Binary, segments),
            _ => (Crate::Library, segments),
        };
        if module.0 == Crate::Library && module.1.first().is_some_and(|s| s == "bin") {
            continue; // a separate binary target, not part of either crate
        }
        let text = std::fs::read_to_string(path)
            .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
        let (tokens, tests) = strip_test_code(tokenize(&text));
        for name in tests {
            let mut child = module.clone();
            child.1.push(name);
            test_only.insert(child);
        }
        files.push(SourceFile {
            relative: format!("{shown}/{relative}"),
            module,
            tokens,
        });
    }
    // A file is test code if it, or a module above it, is declared under
    // `#[cfg(test)]`.
    files.retain(|f| {
        !test_only
            .iter()
            .any(|t| t.0 == f.module.0 && f.module.1.starts_with(&t.1))
    });
    files
}

/// One path that a file names, made absolute.
struct Reference {
    path: AbsPath,
    line: usize,
    text: String,
    /// From a `pub use`: the name under which the current module
    /// re-exports it (`None` for other uses and for globs).
    reexported_as: Option<String>,
    /// Top level of its file (not in an inline module).
    top_level: bool,
}

/// The use-tree leaves of a `use` declaration starting at `tokens[i]`
/// (just past `use`): (segments, alias or last segment, line). Returns the
/// index just past the `;`.
fn parse_use_tree(
    tokens: &[(Token, usize)],
    mut i: usize,
    prefix: &[String],
    out: &mut Vec<(Vec<String>, Option<String>, usize)>,
) -> usize {
    let mut segments = prefix.to_vec();
    let line = tokens.get(i).map_or(0, |t| t.1);
    loop {
        match tokens.get(i).map(|t| &t.0) {
            Some(Token::PathSep) => i += 1,
            Some(Token::Ident(word)) if word != "as" => {
                segments.push(word.clone());
                i += 1;
            }
            Some(Token::Punct('{')) => {
                i += 1;
                loop {
                    match tokens.get(i).map(|t| &t.0) {
                        Some(Token::Punct('}')) => return i + 1,
                        Some(Token::Punct(',')) => i += 1,
                        None => return i,
                        _ => i = parse_use_tree(tokens, i, &segments, out),
                    }
                }
            }
            Some(Token::Punct('*')) => {
                out.push((segments, None, line));
                return i + 1;
            }
            Some(Token::Ident(_)) => {
                // `as alias`; `self as alias` names the module itself.
                if segments.last().is_some_and(|s| s == "self") {
                    segments.pop();
                }
                let alias = match tokens.get(i + 1).map(|t| &t.0) {
                    Some(Token::Ident(alias)) => alias.clone(),
                    _ => String::new(),
                };
                let name = if alias == "_" { None } else { Some(alias) };
                out.push((segments, name, line));
                return i + 2;
            }
            _ => {
                let name = segments.last().cloned();
                let name = if name.as_deref() == Some("self") {
                    segments.pop();
                    segments.last().cloned()
                } else {
                    name
                };
                out.push((segments, name, line));
                return i;
            }
        }
    }
}

/// Makes `segments` (as written in module `current`) absolute, or `None`
/// for a path into another crate. `relative_ok` allows a first segment
/// that names a child module (as `use` paths may).
fn absolute(
    segments: &[String],
    current: &AbsPath,
    children: &dyn Fn(&AbsPath, &str) -> bool,
    relative_ok: bool,
) -> Option<AbsPath> {
    let first = segments.first()?;
    let mut rest = segments;
    let mut base = match first.as_str() {
        "crate" => {
            rest = &segments[1..];
            (current.0, Vec::new())
        }
        "layout_opt" if current.0 == Crate::Binary => {
            rest = &segments[1..];
            (Crate::Library, Vec::new())
        }
        SOLVER_CRATE => {
            rest = &segments[1..];
            (Crate::Solvers, Vec::new())
        }
        "self" => {
            rest = &segments[1..];
            current.clone()
        }
        "super" => {
            let mut base = current.clone();
            while rest.first().is_some_and(|s| s == "super") {
                base.1.pop();
                rest = &rest[1..];
            }
            base
        }
        name if relative_ok && children(current, name) => current.clone(),
        _ => return None,
    };
    base.1.extend(rest.iter().cloned());
    Some(base)
}

/// Every path that a file names, with the module path of the place that
/// names it.
fn references(file: &SourceFile, known: &BTreeSet<AbsPath>) -> Vec<Reference> {
    let tokens = &file.tokens;
    let mut refs = Vec::new();
    // Inline modules open at a brace depth: (name, depth).
    let mut inline: Vec<(String, i32)> = Vec::new();
    let mut inline_names: BTreeSet<AbsPath> = BTreeSet::new();
    let mut depth = 0i32;
    let mut i = 0;
    let current = |inline: &[(String, i32)]| {
        let mut path = file.module.clone();
        path.1.extend(inline.iter().map(|(n, _)| n.clone()));
        path
    };
    while i < tokens.len() {
        let (token, line) = (&tokens[i].0, tokens[i].1);
        match token {
            Token::Punct('{') => {
                depth += 1;
                i += 1;
            }
            Token::Punct('}') => {
                if inline.last().is_some_and(|(_, d)| *d == depth) {
                    inline.pop();
                }
                depth -= 1;
                i += 1;
            }
            Token::Ident(word) if word == "mod" => {
                if let (Some((Token::Ident(name), _)), Some((Token::Punct('{'), _))) =
                    (tokens.get(i + 1), tokens.get(i + 2))
                {
                    inline.push((name.clone(), depth + 1));
                    inline_names.insert(current(&inline));
                    depth += 1;
                    i += 3;
                } else {
                    i += 1;
                }
            }
            Token::Ident(word) if word == "use" => {
                let public = i > 0
                    && (matches!(&tokens[i - 1].0, Token::Ident(w) if w == "pub")
                        || matches!(&tokens[i - 1].0, Token::Punct(')')));
                let mut leaves = Vec::new();
                i = parse_use_tree(tokens, i + 1, &[], &mut leaves);
                let here = current(&inline);
                for (segments, name, use_line) in leaves {
                    let children = |module: &AbsPath, name: &str| {
                        let mut child = module.clone();
                        child.1.push(name.to_string());
                        known.contains(&child) || inline_names.contains(&child)
                    };
                    if let Some(path) = absolute(&segments, &here, &children, true) {
                        refs.push(Reference {
                            path,
                            line: use_line,
                            text: format!("use {}", segments.join("::")),
                            reexported_as: if public { name } else { None },
                            top_level: inline.is_empty(),
                        });
                    }
                }
            }
            Token::Ident(word)
                if matches!(
                    word.as_str(),
                    "crate" | "super" | "self" | "layout_opt" | SOLVER_CRATE
                ) && tokens.get(i + 1).map(|t| &t.0) == Some(&Token::PathSep)
                    && !(i > 0 && tokens[i - 1].0 == Token::PathSep) =>
            {
                let mut segments = vec![word.clone()];
                let mut j = i + 1;
                while tokens.get(j).map(|t| &t.0) == Some(&Token::PathSep) {
                    match tokens.get(j + 1).map(|t| &t.0) {
                        Some(Token::Ident(next)) => {
                            segments.push(next.clone());
                            j += 2;
                        }
                        _ => break,
                    }
                }
                let here = current(&inline);
                let no_children = |_: &AbsPath, _: &str| false;
                if let Some(path) = absolute(&segments, &here, &no_children, false) {
                    refs.push(Reference {
                        path,
                        line,
                        text: segments.join("::"),
                        reexported_as: None,
                        top_level: inline.is_empty(),
                    });
                }
                i = j;
            }
            _ => i += 1,
        }
    }
    refs
}

/// The import graph: edges between file modules, each with where it is.
struct Graph {
    modules: BTreeMap<String, String>,
    /// (from, to) → "src/file.rs:line: path".
    edges: BTreeMap<(String, String), String>,
}

/// The graph of the tool (`library` is [`Crate::Library`]: its library and
/// binary, with the solver crate as the one node [`SOLVER_CRATE`]) or of the
/// solver crate ([`Crate::Solvers`]).
fn build_graph(library: Crate) -> Graph {
    let files = read_sources(library);
    let known: BTreeSet<AbsPath> = files.iter().map(|f| f.module.clone()).collect();
    let all_refs: Vec<Vec<Reference>> = files.iter().map(|f| references(f, &known)).collect();
    // Re-exports: module → name → where it really is.
    let mut reexports: BTreeMap<AbsPath, BTreeMap<String, AbsPath>> = BTreeMap::new();
    for (file, refs) in files.iter().zip(&all_refs) {
        for r in refs {
            if let (Some(name), true) = (&r.reexported_as, r.top_level) {
                reexports
                    .entry(file.module.clone())
                    .or_default()
                    .insert(name.clone(), r.path.clone());
            }
        }
    }
    // The file module that defines the item a path names.
    fn resolve(
        path: &AbsPath,
        known: &BTreeSet<AbsPath>,
        reexports: &BTreeMap<AbsPath, BTreeMap<String, AbsPath>>,
        budget: usize,
    ) -> AbsPath {
        let mut module = (path.0, Vec::new());
        for (index, segment) in path.1.iter().enumerate() {
            let mut child = module.clone();
            child.1.push(segment.clone());
            if known.contains(&child) {
                module = child;
                continue;
            }
            if budget > 0 {
                if let Some(target) = reexports.get(&module).and_then(|m| m.get(segment)) {
                    let mut full = target.clone();
                    full.1.extend(path.1[index + 1..].iter().cloned());
                    if full != *path {
                        return resolve(&full, known, reexports, budget - 1);
                    }
                }
            }
            break;
        }
        module
    }
    let mut graph = Graph {
        modules: BTreeMap::new(),
        edges: BTreeMap::new(),
    };
    for (file, refs) in files.iter().zip(&all_refs) {
        let from = key(&file.module);
        graph.modules.insert(from.clone(), file.relative.clone());
        for r in refs {
            let target = resolve(&r.path, &known, &reexports, 8);
            if target.1.is_empty() && target.0 == library || target == file.module {
                continue;
            }
            let to = key(&target);
            graph
                .edges
                .entry((from.clone(), to))
                .or_insert_with(|| format!("{}:{}: {}", file.relative, r.line, r.text));
        }
    }
    graph.modules.remove(&key(&(library, Vec::new())));
    graph
}

/// Whether `a` is `b` or a module inside `b`.
fn within(a: &str, b: &str) -> bool {
    a == b || a.starts_with(&format!("{b}/"))
}

/// Layers (bottom first) and each documented module's layer, from
/// docs/architecture.md: a numbered list of `**layer**` names, and table
/// rows `` | `module` | layer | job | ``. The tool's are those above the
/// heading [`SOLVER_SECTION`]; the solver crate's (`solver_crate`) those
/// below it.
fn read_layers(solver_crate: bool) -> (Vec<String>, BTreeMap<String, (String, usize)>) {
    let text = std::fs::read_to_string(layer_doc()).expect("docs/architecture.md exists");
    let lines: Vec<&str> = text.lines().collect();
    let split = lines
        .iter()
        .position(|line| line.trim() == SOLVER_SECTION)
        .unwrap_or_else(|| panic!("docs/architecture.md must have a section `{SOLVER_SECTION}`"));
    let range = if solver_crate {
        split..lines.len()
    } else {
        0..split
    };
    let mut layers = Vec::new();
    let mut modules = BTreeMap::new();
    for number in range {
        let line = lines[number].trim();
        if let Some(rest) = line
            .split_once(". **")
            .filter(|(n, _)| n.parse::<usize>().is_ok())
        {
            if let Some((name, _)) = rest.1.split_once("**") {
                layers.push(name.to_string());
            }
        } else if let Some(row) = line.strip_prefix("| `") {
            let cells: Vec<&str> = row.split('|').map(str::trim).collect();
            if cells.len() >= 2 {
                let module = cells[0].trim_end_matches('`').to_string();
                modules.insert(module, (cells[1].to_string(), number + 1));
            }
        }
    }
    (layers, modules)
}

/// Strongly connected components with more than one module (Tarjan).
fn circles(nodes: &BTreeSet<String>, edges: &BTreeSet<(String, String)>) -> Vec<Vec<String>> {
    let names: Vec<&String> = nodes.iter().collect();
    let index_of: BTreeMap<&String, usize> =
        names.iter().enumerate().map(|(i, n)| (*n, i)).collect();
    let mut adjacency = vec![Vec::new(); names.len()];
    for (a, b) in edges {
        adjacency[index_of[a]].push(index_of[b]);
    }
    struct State {
        index: Vec<Option<usize>>,
        low: Vec<usize>,
        on_stack: Vec<bool>,
        stack: Vec<usize>,
        next: usize,
        components: Vec<Vec<usize>>,
    }
    fn visit(v: usize, adjacency: &[Vec<usize>], s: &mut State) {
        s.index[v] = Some(s.next);
        s.low[v] = s.next;
        s.next += 1;
        s.stack.push(v);
        s.on_stack[v] = true;
        for &w in &adjacency[v] {
            match s.index[w] {
                None => {
                    visit(w, adjacency, s);
                    s.low[v] = s.low[v].min(s.low[w]);
                }
                Some(index) if s.on_stack[w] => s.low[v] = s.low[v].min(index),
                _ => {}
            }
        }
        if Some(s.low[v]) == s.index[v] {
            let mut component = Vec::new();
            while let Some(w) = s.stack.pop() {
                s.on_stack[w] = false;
                component.push(w);
                if w == v {
                    break;
                }
            }
            if component.len() > 1 {
                s.components.push(component);
            }
        }
    }
    let mut state = State {
        index: vec![None; names.len()],
        low: vec![0; names.len()],
        on_stack: vec![false; names.len()],
        stack: Vec::new(),
        next: 0,
        components: Vec::new(),
    };
    for v in 0..names.len() {
        if state.index[v].is_none() {
            visit(v, &adjacency, &mut state);
        }
    }
    let mut out: Vec<Vec<String>> = state
        .components
        .into_iter()
        .map(|c| {
            let mut c: Vec<String> = c.into_iter().map(|i| names[i].clone()).collect();
            c.sort();
            c
        })
        .collect();
    out.sort();
    out
}

/// What breaks the floors of one crate's graph: a documented module that
/// is not on a listed floor or does not exist, a module without a floor, an
/// import that goes up a floor, a circle. `sources` names the source tree
/// and `section` the part of docs/architecture.md, for the messages. With
/// `below_every_floor`, that node (the solver crate, in the tool's graph)
/// is on a floor of its own under the first listed one.
fn layer_problems(
    graph: &Graph,
    layers: &[String],
    documented: &BTreeMap<String, (String, usize)>,
    sources: &str,
    section: &str,
    below_every_floor: Option<&str>,
) -> Vec<String> {
    let mut problems = Vec::new();
    for (module, (layer, line)) in documented {
        if !layers.contains(layer) {
            problems.push(format!(
                "docs/architecture.md:{line}: module `{module}` is in layer `{layer}`, which is not one of the layers listed ({})",
                layers.join(", ")
            ));
        }
        if !graph.modules.keys().any(|m| within(m, module)) {
            problems.push(format!(
                "docs/architecture.md:{line}: module `{module}` does not exist in {sources}/; remove or rename its line"
            ));
        }
    }
    // The layer of a module: its own line, or its nearest documented
    // ancestor's; the node below every floor is under the first (rank 0,
    // the listed floors from 1).
    let layer_of = |module: &str| -> Option<(usize, String, String)> {
        if below_every_floor == Some(module) {
            return Some((
                0,
                "below every floor".to_string(),
                "the solver crate".to_string(),
            ));
        }
        let owner = documented
            .keys()
            .filter(|d| within(module, d))
            .max_by_key(|d| d.len())?;
        let layer = &documented[owner].0;
        let rank = layers.iter().position(|l| l == layer)? + 1;
        Some((rank, layer.clone(), owner.clone()))
    };
    for (module, file) in &graph.modules {
        if layer_of(module).is_none() {
            problems.push(format!(
                "module `{module}` ({file}) has no layer: add a line `| `{module}` | <layer> | <job> |` (or one for a module above it) to {section}"
            ));
        }
    }
    for ((from, to), place) in &graph.edges {
        if let (Some((from_rank, from_layer, from_doc)), Some((to_rank, to_layer, to_doc))) =
            (layer_of(from), layer_of(to))
        {
            if to_rank > from_rank {
                problems.push(format!(
                    "upward import: `{from}` (layer {from_layer}, from `{from_doc}`) imports `{to}` (layer {to_layer}, from `{to_doc}`) at {place}"
                ));
            }
        }
    }
    let nodes: BTreeSet<String> = graph.modules.keys().cloned().collect();
    let cycle_edges: BTreeSet<(String, String)> = graph
        .edges
        .keys()
        .filter(|(a, b)| nodes.contains(a) && nodes.contains(b) && !within(a, b) && !within(b, a))
        .cloned()
        .collect();
    for component in circles(&nodes, &cycle_edges) {
        let members: BTreeSet<&String> = component.iter().collect();
        let inside: Vec<String> = cycle_edges
            .iter()
            .filter(|(a, b)| members.contains(a) && members.contains(b))
            .map(|(a, b)| {
                format!(
                    "    `{a}` → `{b}` at {}",
                    graph.edges[&(a.clone(), b.clone())]
                )
            })
            .collect();
        problems.push(format!(
            "circle among {}; its imports:\n{}",
            component
                .iter()
                .map(|m| format!("`{m}`"))
                .collect::<Vec<_>>()
                .join(", "),
            inside.join("\n")
        ));
    }
    problems
}

/// Every module has a layer in docs/architecture.md, every documented
/// module exists, no import goes up a layer, and no import goes round in a
/// circle. The solver crate is below every floor: any module may import
/// it.
#[test]
fn imports_go_down_the_layers_without_circles() {
    let graph = build_graph(Crate::Library);
    let (layers, documented) = read_layers(false);
    assert!(
        layers.len() >= 2,
        "docs/architecture.md must list the layers as a numbered list of **names**, bottom first"
    );
    let problems = layer_problems(
        &graph,
        &layers,
        &documented,
        "src",
        "docs/architecture.md",
        Some(SOLVER_CRATE),
    );
    assert!(
        problems.is_empty(),
        "the import graph breaks docs/architecture.md ({} problems):\n{}",
        problems.len(),
        problems.join("\n")
    );
}

/// The same inside the solver crate, against the floors and table of the
/// section "The solver crate" of docs/architecture.md.
#[test]
fn the_solver_crate_s_imports_go_down_its_layers_without_circles() {
    let graph = build_graph(Crate::Solvers);
    let (layers, documented) = read_layers(true);
    assert!(
        layers.len() >= 2,
        "docs/architecture.md, section `{SOLVER_SECTION}`, must list the solver crate's layers as a numbered list of **names**, bottom first"
    );
    let section = format!("docs/architecture.md (section `{SOLVER_SECTION}`)");
    let problems = layer_problems(
        &graph,
        &layers,
        &documented,
        "crates/solvers/src",
        &section,
        None,
    );
    assert!(
        problems.is_empty(),
        "the solver crate's import graph breaks docs/architecture.md ({} problems):\n{}",
        problems.len(),
        problems.join("\n")
    );
}

/// The graph builder sees imports written every way the crate writes them,
/// and skips comments, strings and test code; so the test above can fail.
#[test]
fn the_graph_builder_finds_the_imports_it_must() {
    let graph = build_graph(Crate::Library);
    let edge = |a: &str, b: &str| graph.edges.contains_key(&(a.to_string(), b.to_string()));
    let solvers = build_graph(Crate::Solvers);
    let solver_edge =
        |a: &str, b: &str| solvers.edges.contains_key(&(a.to_string(), b.to_string()));
    // `use super::…` in a solver file, to its sibling.
    assert!(solver_edge("pnp/gauss_newton", "pnp/epnp"));
    // `use crate::…` across the tree, through the `pub use` re-exports of
    // linalg/mod.rs to the file that defines the item.
    assert!(solver_edge("pnp/epnp", "linalg/eigenpairs"));
    assert!(!solver_edge("pnp/epnp", "linalg"));
    // `layout_opt::…` from the binary, to the library's own module and,
    // through src/lib.rs's re-export of `pnp`, to the solver crate.
    assert!(edge("cli/solve", "batch"));
    assert!(edge("cli/solve", SOLVER_CRATE));
    // `crate::pnp::…` in the library, through the same re-export.
    assert!(edge("montecarlo", SOLVER_CRATE));
    // A `layout_opt_solvers::…` path (src/camera.rs re-exports the model).
    assert!(edge("camera", SOLVER_CRATE));
    // Through src/camera.rs: `Camera` is the solver crate's, `CameraSpec`
    // the tool's own.
    assert!(edge("batch", SOLVER_CRATE));
    assert!(edge("batch", "camera"));
    // `use crate::{…}`-style trees and re-exports are followed.
    let tokens = tokenize("use crate::{a::{b, c as d}, e::*}; // crate::x::y\nlet s = \"crate::z::w\"; let c = '\"'; let r = r#\"crate::v::u\"#; r#type(); crate::f::g();");
    let mut leaves = Vec::new();
    parse_use_tree(&tokens, 1, &[], &mut leaves);
    let paths: Vec<String> = leaves.iter().map(|(s, _, _)| s.join("::")).collect();
    assert_eq!(paths, ["crate::a::b", "crate::a::c", "crate::e"]);
    let words: Vec<String> = tokens
        .iter()
        .filter_map(|(t, _)| match t {
            Token::Ident(w) => Some(w.clone()),
            _ => None,
        })
        .collect();
    for hidden in ["x", "z", "v"] {
        assert!(
            !words.contains(&hidden.to_string()),
            "{hidden} is in a comment or string"
        );
    }
    assert!(words.contains(&"type".to_string()));
    assert!(words.contains(&"f".to_string()));
    let (kept, test_modules) = strip_test_code(tokenize(
        "use a::b;\n#[cfg(test)]\nmod tests { use crate::q::r; }\n#[cfg(test)]\nmod more;\nfn f() {}",
    ));
    assert!(!kept.iter().any(|(t, _)| *t == Token::Ident("q".into())));
    assert!(kept.iter().any(|(t, _)| *t == Token::Ident("f".into())));
    assert_eq!(test_modules.into_iter().collect::<Vec<_>>(), ["more"]);
    // A circle is found.
    let nodes: BTreeSet<String> = ["a", "b", "c"].iter().map(|s| s.to_string()).collect();
    let edges: BTreeSet<(String, String)> = [("a", "b"), ("b", "c"), ("c", "a")]
        .iter()
        .map(|(a, b)| (a.to_string(), b.to_string()))
        .collect();
    assert_eq!(circles(&nodes, &edges), vec![vec!["a", "b", "c"]]);
}
