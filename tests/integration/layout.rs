//! The shape of the workspace, checked from its sources (issue 29): the facade stays thin, no
//! library source file grows past 1000 lines of non-test code, and no two files of a crate
//! import each other (a file and its own parent module re-exporting it do not count: that is
//! how a Rust module exposes its children).
//!
//! "Non-test lines" are the lines of a file outside `#[cfg(test)]` items; files named
//! `tests.rs` and `tests/` folders are all test code.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

/// The most non-test lines of the facade crate `crates/balloon`.
const FACADE_LIMIT: usize = 2500;
/// The most non-test lines of one library source file.
const FILE_LIMIT: usize = 1000;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("the tests crate sits in the workspace")
        .to_path_buf()
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            if path.file_name().is_some_and(|n| n == "tests") {
                continue;
            }
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs")
            && path.file_name().is_some_and(|n| n != "tests.rs")
        {
            out.push(path);
        }
    }
}

/// The lines of `text` outside `#[cfg(test)]` items (a `mod x;` line or a braced item).
fn non_test_lines(text: &str) -> Vec<&str> {
    let lines: Vec<&str> = text.lines().collect();
    let mut kept = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        if lines[i].trim_start().starts_with("#[cfg(test)]") {
            let mut j = i + 1;
            while j < lines.len() && lines[j].trim_start().starts_with("#[") {
                j += 1;
            }
            if j < lines.len() && lines[j].trim_end().ends_with(';') {
                i = j + 1;
                continue;
            }
            let (mut depth, mut opened) = (0i64, false);
            while j < lines.len() {
                let l = lines[j];
                depth += l.matches('{').count() as i64 - l.matches('}').count() as i64;
                opened |= l.contains('{');
                j += 1;
                if opened && depth <= 0 {
                    break;
                }
            }
            i = j;
            continue;
        }
        kept.push(lines[i]);
        i += 1;
    }
    kept
}

/// The library source folders: every crate's `src/` and the Python package's.
fn library_sources() -> Vec<(String, PathBuf)> {
    let root = root();
    let mut out = Vec::new();
    for entry in fs::read_dir(root.join("crates"))
        .expect("crates/")
        .flatten()
    {
        let src = entry.path().join("src");
        if src.is_dir() {
            out.push((entry.file_name().to_string_lossy().into_owned(), src));
        }
    }
    out.push(("python".into(), root.join("python").join("src")));
    out.sort();
    out
}

#[test]
fn the_facade_is_thin_and_no_library_file_is_long() {
    let mut over = Vec::new();
    let mut facade = 0;
    for (krate, src) in library_sources() {
        let mut files = Vec::new();
        rust_files(&src, &mut files);
        for file in files {
            let text = fs::read_to_string(&file).expect("readable source");
            let n = non_test_lines(&text).len();
            if krate == "balloon" {
                facade += n;
            }
            if n > FILE_LIMIT {
                over.push(format!("{} ({n})", file.display()));
            }
        }
    }
    assert!(
        over.is_empty(),
        "library files over {FILE_LIMIT} non-test lines: {over:?}"
    );
    assert!(
        facade <= FACADE_LIMIT,
        "the facade crate has {facade} non-test lines, more than {FACADE_LIMIT}: move numerics to \
         the stage crates"
    );
}

/// The module path (`["newton", "convergence"]`) of a source file under `src`.
fn module_of(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).expect("under src");
    let mut parts: Vec<String> = rel
        .iter()
        .map(|p| p.to_string_lossy().trim_end_matches(".rs").to_string())
        .collect();
    if matches!(
        parts.last().map(String::as_str),
        Some("mod" | "lib" | "main")
    ) {
        parts.pop();
    }
    parts
}

/// The paths written out in code (`crate::runner::first_non_finite(..)`, `super::x::y`) of a
/// file's non-test code, outside `use` statements.
fn inline_paths(text: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    for line in non_test_lines(text) {
        let code = line.split("//").next().unwrap_or("");
        if code.trim_start().starts_with("use ") || code.trim_start().starts_with("pub use ") {
            continue;
        }
        for start in ["crate::", "super::"] {
            let mut rest = code;
            while let Some(at) = rest.find(start) {
                let before = rest[..at].chars().last();
                let tail = &rest[at..];
                let end = tail
                    .find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
                    .unwrap_or(tail.len());
                if !before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
                    out.push(
                        tail[..end]
                            .split("::")
                            .filter(|s| !s.is_empty())
                            .map(str::to_string)
                            .collect(),
                    );
                }
                rest = &tail[end.max(1)..];
            }
        }
    }
    out
}

/// The `use` paths of a file's non-test code, `{a, b}` groups expanded one level, as segment
/// lists (`crate::newton::Residual` -> `["crate", "newton", "Residual"]`).
fn use_paths(text: &str) -> Vec<Vec<String>> {
    let code: String = non_test_lines(text)
        .into_iter()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n");
    let mut out = Vec::new();
    for stmt in code.split(';') {
        let Some(at) = stmt.find("use ") else {
            continue;
        };
        let before = &stmt[..at];
        if !(before.trim().is_empty()
            || before.trim_end().ends_with("pub")
            || before.trim_end().ends_with(')'))
        {
            continue;
        }
        let body: String = stmt[at + 4..]
            .chars()
            .filter(|c| !c.is_whitespace())
            .collect();
        let (prefix, group) = match body.find('{') {
            Some(b) => (&body[..b], body[b + 1..].trim_end_matches('}').to_string()),
            None => (body.as_str(), String::new()),
        };
        let prefix: Vec<String> = prefix
            .split("::")
            .filter(|s| !s.is_empty())
            .map(str::to_string)
            .collect();
        if group.is_empty() {
            out.push(prefix);
        } else {
            for item in group.split(',').filter(|s| !s.is_empty()) {
                let mut p = prefix.clone();
                p.extend(
                    item.split('{')
                        .next()
                        .unwrap_or("")
                        .split("::")
                        .filter(|s| !s.is_empty())
                        .map(str::to_string),
                );
                out.push(p);
            }
        }
    }
    out
}

#[test]
fn no_two_files_of_a_crate_import_each_other() {
    let mut circles = Vec::new();
    for (krate, src) in library_sources() {
        let mut files = Vec::new();
        rust_files(&src, &mut files);
        let modules: BTreeMap<Vec<String>, PathBuf> = files
            .iter()
            .map(|f| (module_of(&src, f), f.clone()))
            .collect();
        let mut edges: BTreeSet<(Vec<String>, Vec<String>)> = BTreeSet::new();
        for (module, file) in &modules {
            let text = fs::read_to_string(file).expect("readable source");
            for path in use_paths(&text).into_iter().chain(inline_paths(&text)) {
                // Resolve `crate::` and `super::` to an absolute module path.
                let mut target: Vec<String> = match path.first().map(String::as_str) {
                    Some("crate") => Vec::new(),
                    Some("super") => {
                        let mut m = module.clone();
                        m.pop();
                        m
                    }
                    Some("self") => module.clone(),
                    _ => continue,
                };
                let mut rest = path[1..].iter().peekable();
                while rest.peek().is_some_and(|s| *s == "super") {
                    target.pop();
                    rest.next();
                }
                // The deepest module file the path names.
                let mut best = target.clone();
                for seg in rest {
                    target.push(seg.clone());
                    if modules.contains_key(&target) {
                        best = target.clone();
                    } else {
                        break;
                    }
                }
                // A file and its ancestors (their `mod` and re-exports) do not count.
                if best.len() <= module.len() && module.starts_with(&best)
                    || best.starts_with(module)
                {
                    continue;
                }
                edges.insert((module.clone(), best));
            }
        }
        for (a, b) in &edges {
            if a < b && edges.contains(&(b.clone(), a.clone())) {
                circles.push(format!("{krate}: {} <-> {}", a.join("/"), b.join("/")));
            }
        }
    }
    assert!(
        circles.is_empty(),
        "files importing each other: {circles:#?}"
    );
}

#[test]
fn the_line_counter_skips_test_items() {
    let text = "fn a() {}\n#[cfg(test)]\nmod tests {\n    fn b() {}\n}\n#[cfg(test)]\nmod more;\nfn c() {}\n";
    assert_eq!(non_test_lines(text), vec!["fn a() {}", "fn c() {}"]);
    let uses = use_paths("use crate::a::{b, c::D};\npub use super::e::F;\n");
    assert_eq!(
        uses,
        vec![
            vec!["crate", "a", "b"],
            vec!["crate", "a", "c", "D"],
            vec!["super", "e", "F"]
        ]
    );
}
