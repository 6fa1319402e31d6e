//! The house's floors: within each crate of the workspace, no file imports a module that
//! imports it back, directly or round a longer circle; and each crate's top-level modules (its
//! folders by concern) stand on floors, each importing only from the floors below it.
//!
//! Each file's `crate::` and `super::` paths (in `use` lines and in code, doc comments and the
//! in-file `#[cfg(test)]` module aside) are read with a small parser of this file's own, and
//! resolved to the deepest module file of the crate they name; a name the crate's root
//! re-exports (`pub use module::Name`) resolves to that module. The circles are the strongly
//! connected components of the graph of those imports (Tarjan's algorithm).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The crate's module files by module path (`""` for the root, `"a::b"` for `src/a/b.rs` or
/// `src/a/b/mod.rs`).
fn modules(src: &Path) -> BTreeMap<String, PathBuf> {
    let mut found = BTreeMap::new();
    let mut folders = vec![src.to_path_buf()];
    while let Some(folder) = folders.pop() {
        for entry in std::fs::read_dir(&folder).expect("a readable source folder") {
            let path = entry.expect("a readable entry").path();
            if path.is_dir() {
                folders.push(path);
                continue;
            }
            if path.extension().is_none_or(|e| e != "rs") {
                continue;
            }
            let relative = path.strip_prefix(src).expect("under src").with_extension("");
            let mut parts: Vec<String> = relative.iter().map(|p| p.to_string_lossy().into_owned()).collect();
            if parts.last().is_some_and(|p| p == "mod") {
                parts.pop();
            }
            if parts == ["lib"] {
                parts.clear();
            }
            found.insert(parts.join("::"), path);
        }
    }
    found
}

/// The file's code: no comment lines, nothing from its `#[cfg(test)]` module on.
fn code(text: &str) -> String {
    let mut kept = String::new();
    let mut lines = text.lines().peekable();
    while let Some(line) = lines.next() {
        let trimmed = line.trim();
        if trimmed == "#[cfg(test)]" && lines.peek().is_some_and(|next| next.trim_start().starts_with("mod ")) {
            break;
        }
        if trimmed.starts_with("//") {
            continue;
        }
        kept.push_str(line);
        kept.push('\n');
    }
    kept
}

/// A cursor over a path after `crate::` or `super::`.
struct Paths<'a> {
    text: &'a [u8],
    at: usize,
    found: Vec<Vec<String>>,
}

impl Paths<'_> {
    fn skip_space(&mut self) {
        while self.at < self.text.len() && self.text[self.at].is_ascii_whitespace() {
            self.at += 1;
        }
    }

    fn eat(&mut self, token: &str) -> bool {
        self.skip_space();
        if self.text[self.at..].starts_with(token.as_bytes()) {
            self.at += token.len();
            true
        } else {
            false
        }
    }

    fn ident(&mut self) -> Option<String> {
        self.skip_space();
        let start = self.at;
        while self.at < self.text.len() && (self.text[self.at].is_ascii_alphanumeric() || self.text[self.at] == b'_') {
            self.at += 1;
        }
        (self.at > start && !self.text[start].is_ascii_digit())
            .then(|| String::from_utf8_lossy(&self.text[start..self.at]).into_owned())
    }

    /// One path (or group of paths) from here, each prefixed by `prefix`.
    fn parse(&mut self, prefix: Vec<String>) {
        let mut segments = prefix;
        loop {
            let Some(name) = self.ident() else {
                self.eat("*");
                self.found.push(segments);
                return;
            };
            if name == "self" {
                self.found.push(segments);
                return;
            }
            segments.push(name);
            if !self.eat("::") {
                self.found.push(segments);
                return;
            }
            if self.eat("{") {
                loop {
                    self.parse(segments.clone());
                    let comma = self.eat(",");
                    if self.eat("}") || !comma {
                        return;
                    }
                }
            }
        }
    }
}

/// The paths after each `anchor` (`crate::` or `super::`) in `text`.
fn paths_after(text: &str, anchor: &str) -> Vec<Vec<String>> {
    let bytes = text.as_bytes();
    let mut paths = Paths { text: bytes, at: 0, found: Vec::new() };
    let mut from = 0;
    while let Some(offset) = text[from..].find(anchor) {
        let start = from + offset;
        from = start + anchor.len();
        let joined = start > 0 && (bytes[start - 1].is_ascii_alphanumeric() || bytes[start - 1] == b'_');
        if joined {
            continue;
        }
        paths.at = from;
        paths.parse(Vec::new());
    }
    paths.found
}

/// The deepest module of `modules` that `path` names, if any.
fn resolve(modules: &BTreeMap<String, PathBuf>, path: &[String]) -> Option<String> {
    (1..=path.len()).rev().map(|k| path[..k].join("::")).find(|m| modules.contains_key(m))
}

/// Each module's imports of the crate's other modules (its own submodules and ancestors aside).
fn imports(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let modules = modules(src);
    let root = code(&std::fs::read_to_string(&modules[""]).expect("a readable root"));
    // Names the root re-exports from its modules.
    let mut reexported = BTreeMap::new();
    for path in paths_after(&root.replace("pub use ", "pub use crate::"), "crate::") {
        if path.len() >= 2 && modules.contains_key(&path[0]) {
            reexported.insert(path[path.len() - 1].clone(), path[0].clone());
        }
    }
    let mut graph = BTreeMap::new();
    for (module, file) in &modules {
        if module.is_empty() {
            continue;
        }
        let text = code(&std::fs::read_to_string(file).expect("a readable module"));
        let mut parent: Vec<String> = module.split("::").map(String::from).collect();
        parent.pop();
        let mut named = Vec::new();
        for path in paths_after(&text, "crate::") {
            named.push(resolve(&modules, &path).or_else(|| path.first().and_then(|n| reexported.get(n).cloned())));
        }
        for path in paths_after(&text, "super::") {
            let full: Vec<String> = parent.iter().cloned().chain(path).collect();
            named.push(resolve(&modules, &full));
        }
        let own =
            |m: &String| m == module || module.starts_with(&format!("{m}::")) || m.starts_with(&format!("{module}::"));
        let deps: BTreeSet<String> = named.into_iter().flatten().filter(|m| !m.is_empty() && !own(m)).collect();
        graph.insert(module.clone(), deps);
    }
    graph
}

/// The strongly connected components of more than one module.
fn circles(graph: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct Tarjan<'a> {
        graph: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on_stack: BTreeSet<&'a str>,
        found: Vec<Vec<String>>,
    }
    impl<'a> Tarjan<'a> {
        fn visit(&mut self, v: &'a str) {
            let n = self.index.len();
            self.index.insert(v, n);
            self.low.insert(v, n);
            self.stack.push(v);
            self.on_stack.insert(v);
            for w in self.graph.get(v).into_iter().flatten() {
                let w = w.as_str();
                if !self.index.contains_key(w) {
                    self.visit(w);
                    let low = self.low[v].min(self.low[w]);
                    self.low.insert(v, low);
                } else if self.on_stack.contains(w) {
                    let low = self.low[v].min(self.index[w]);
                    self.low.insert(v, low);
                }
            }
            if self.low[v] == self.index[v] {
                let mut component = Vec::new();
                while let Some(w) = self.stack.pop() {
                    self.on_stack.remove(w);
                    component.push(w.to_string());
                    if w == v {
                        break;
                    }
                }
                if component.len() > 1 {
                    component.sort();
                    self.found.push(component);
                }
            }
        }
    }
    let mut tarjan = Tarjan {
        graph,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        found: Vec::new(),
    };
    for v in graph.keys() {
        if !tarjan.index.contains_key(v.as_str()) {
            tarjan.visit(v);
        }
    }
    tarjan.found
}

/// The parser on the forms the crates use, and the circle finder on a made-up graph.
#[test]
fn the_checker_reads_paths_and_finds_circles() {
    let text = "use crate::a::{B, c::{D, e}, self};\nlet x = crate::f::g(1);\nuse crate::h::*;";
    let found: Vec<String> = paths_after(text, "crate::").iter().map(|p| p.join("::")).collect();
    assert_eq!(found, ["a::B", "a::c::D", "a::c::e", "a", "f::g", "h"]);
    let graph: BTreeMap<String, BTreeSet<String>> = [("a", &["b"][..]), ("b", &["c"]), ("c", &["a"]), ("d", &["a"])]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v.iter().map(|s| s.to_string()).collect()))
        .collect();
    assert_eq!(circles(&graph), [["a", "b", "c"]]);
}

/// Every crate of the workspace, its source files read as they are.
#[test]
fn no_crate_has_an_import_circle() {
    let crates = Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("the crates folder");
    let mut checked = 0;
    for entry in std::fs::read_dir(crates).expect("a readable crates folder") {
        let src = entry.expect("a readable entry").path().join("src");
        if !src.join("lib.rs").exists() {
            continue;
        }
        let graph = imports(&src);
        let edges: usize = graph.values().map(BTreeSet::len).sum();
        assert!(graph.len() < 2 || edges > 0, "{}: no import found, the parser reads nothing", src.display());
        let found = circles(&graph);
        assert!(found.is_empty(), "{}: modules that import one another round a circle: {found:?}", src.display());
        checked += 1;
    }
    assert!(checked >= 4, "only {checked} crates checked");
}

/// Each crate's top-level modules by floor, from the bottom: a module may import from a lower
/// floor, never from its own or a higher one (the re-exporting root aside). Each folder's
/// `mod.rs` says the same in words.
const FLOORS: &[(&str, &[&[&str]])] = &[
    (
        "bvh_cloth_core",
        &[&["mesh", "bvh"], &["cloth", "colliders"], &["air", "self_contact"], &["solver"], &["sim"], &["backend"]],
    ),
    (
        "bvh_cloth_gpu",
        &[
            &["layout", "buffer"],
            &["constants"],
            &["kernels"],
            &["headless"],
            &["colliders", "readback", "stages"],
            &["batch"],
        ],
    ),
];

/// Imports across top-level modules that do not run down a floor, as `from -> to`.
fn upward_imports(graph: &BTreeMap<String, BTreeSet<String>>, floors: &[&[&str]]) -> Vec<String> {
    let top = |m: &str| m.split("::").next().unwrap_or_default().to_string();
    let floor = |m: &str| floors.iter().position(|f| f.contains(&top(m).as_str()));
    let mut found = Vec::new();
    for (from, deps) in graph {
        for to in deps {
            if top(from) == top(to) {
                continue;
            }
            match (floor(from), floor(to)) {
                (Some(a), Some(b)) if a > b => {}
                _ => found.push(format!("{from} -> {to}")),
            }
        }
    }
    found
}

/// The floor check on a made-up graph: down is fine, across and up are named.
#[test]
fn the_checker_finds_imports_up_and_across() {
    let graph: BTreeMap<String, BTreeSet<String>> =
        [("b::x", &["a::y", "a"][..]), ("a::y", &["b::x"]), ("a", &["c"]), ("c::z", &["b::x"])]
            .into_iter()
            .map(|(k, v)| (k.to_string(), v.iter().map(|s| s.to_string()).collect()))
            .collect();
    assert_eq!(upward_imports(&graph, &[&["a"], &["b"]]), ["a -> c", "a::y -> b::x", "c::z -> b::x"]);
}

/// Every top-level module of each crate listed in [`FLOORS`] has a floor, and imports only
/// from below it.
#[test]
fn each_crate_imports_only_down_its_floors() {
    let crates = Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("the crates folder");
    for &(name, floors) in FLOORS {
        let src = crates.join(name).join("src");
        let graph = imports(&src);
        let tops: BTreeSet<&str> = graph.keys().map(|m| m.split("::").next().unwrap_or_default()).collect();
        let unplaced: Vec<&&str> = tops.iter().filter(|t| !floors.iter().any(|f| f.contains(t))).collect();
        assert!(unplaced.is_empty(), "{name}: modules on no floor: {unplaced:?}");
        let up = upward_imports(&graph, floors);
        assert!(up.is_empty(), "{name}: imports that do not run down a floor: {up:?}");
    }
}
