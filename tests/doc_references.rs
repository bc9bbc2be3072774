//! The project's documents and the code agree (docs/design.md, "Code
//! conventions"):
//!
//! - every reference to a document (`docs/numerics.md, "Rounding allowance"`,
//!   `docs/design.md section 5`, a Markdown link) names a file that exists
//!   and, where it names a section, a heading that exists;
//! - nothing points at a document outside the repository or at an issue
//!   number (a maintainer cannot follow those);
//! - every named tolerance of the compiler and the engine is named in
//!   docs/numerics.md or docs/design.md;
//! - the picture of the layers in docs/design.md lists every module of the
//!   plugin crate, and no module imports one drawn above it;
//! - no two source files import each other, directly or around a circle
//!   (in the plugin crate and in xtask);
//! - the README's embedding example is the crate documentation's doctest;
//! - every file of `tests/` is in exactly one test binary of Cargo.toml.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Every source and document file of the workspace (not build output, not
/// the gitignored report directory).
fn project_files() -> Vec<PathBuf> {
    let root = root();
    let mut out = Vec::new();
    let mut stack = vec![root.clone()];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).expect("read dir") {
            let p = e.expect("entry").path();
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            if p.is_dir() {
                let rel = p.strip_prefix(&root).unwrap();
                let skip = name.starts_with('.') && name != ".ci"
                    || rel == Path::new("target")
                    || rel == Path::new("report")
                    || name == "node_modules";
                if !skip {
                    stack.push(p);
                }
            } else if ["rs", "md", "toml", "py"]
                .iter()
                .any(|x| p.extension().is_some_and(|e| e == *x))
                || p.ends_with(".ci/run")
            {
                out.push(p);
            }
        }
    }
    out.sort();
    assert!(out.len() > 50, "found only {} files", out.len());
    out
}

/// Section titles of a Markdown file, without their numbers ("6.4
/// Certified isolation of the first crossing" -> both "6.4" and the title).
fn headings(path: &Path) -> (Vec<String>, Vec<String>) {
    let text = std::fs::read_to_string(path).expect("read doc");
    let (mut titles, mut numbers) = (Vec::new(), Vec::new());
    let mut in_code = false;
    for line in text.lines() {
        if line.starts_with("```") {
            in_code = !in_code;
        }
        if in_code || !line.starts_with('#') {
            continue;
        }
        let h = line.trim_start_matches('#').trim();
        let num: String = h
            .chars()
            .take_while(|c| c.is_ascii_digit() || *c == '.')
            .collect();
        let title = h[num.len()..].trim().to_string();
        if !num.is_empty() {
            numbers.push(num.trim_end_matches('.').to_string());
        }
        titles.push(title);
    }
    (titles, numbers)
}

/// The text after a reference with comment markers, string escapes and
/// line breaks folded into single spaces (a title may wrap in a comment).
fn fold(rest: &str, max: usize) -> String {
    let mut out = String::new();
    let mut space = false;
    for line in rest.lines().take(4) {
        let t = line.trim_start();
        let t = t
            .trim_start_matches("//!")
            .trim_start_matches("///")
            .trim_start_matches("//")
            .trim_start_matches('#')
            .trim_start_matches('"')
            .trim_start_matches('\\');
        for c in t.chars() {
            if c.is_whitespace() {
                space = true;
            } else {
                if space && !out.is_empty() {
                    out.push(' ');
                }
                space = false;
                out.push(c);
            }
        }
        space = true;
        if out.len() > max {
            break;
        }
    }
    out.replace("\\\"", "\"")
}

#[test]
fn document_references_resolve() {
    let root = root();
    let this = root.join("tests/doc_references.rs");
    let mut docs: BTreeMap<String, (Vec<String>, Vec<String>)> = BTreeMap::new();
    for e in std::fs::read_dir(root.join("docs")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "md") {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            docs.insert(name, headings(&p));
        }
    }
    // Names of documents that are not in the repository, built so that this
    // file does not contain them itself.
    let outside = [
        ["DESIGN", ".md"].concat(),
        ["NUMERICS", ".md"].concat(),
        ["STYLE", ".md"].concat(),
        ["..", "/shared"].concat(),
        ["issue", " #"].concat(),
        ["Issue", " #"].concat(),
    ];
    let mut problems = Vec::new();
    let mut checked = 0;
    for f in project_files() {
        if f == this {
            continue;
        }
        let text = std::fs::read_to_string(&f).unwrap_or_default();
        let rel = f.strip_prefix(&root).unwrap().display().to_string();
        for bad in &outside {
            if text.contains(bad.as_str()) {
                problems.push(format!("{rel}: points at {bad:?}"));
            }
        }
        // `docs/<name>.md` anywhere; inside docs/, also `](<name>.md)` links
        let mut refs: Vec<(usize, String)> = Vec::new();
        for (i, _) in text.match_indices("docs/") {
            let tail = &text[i + 5..];
            let name: String = tail
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '-' || *c == '_')
                .collect();
            if tail[name.len()..].starts_with(".md") && !name.is_empty() {
                refs.push((i + 5 + name.len() + 3, format!("{name}.md")));
            }
        }
        if rel.starts_with("docs/") {
            for (i, _) in text.match_indices("](") {
                let tail = &text[i + 2..];
                let name: String = tail
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '-' || *c == '_')
                    .collect();
                if tail[name.len()..].starts_with(".md") && !name.is_empty() {
                    refs.push((i + 2 + name.len() + 3, format!("{name}.md")));
                }
            }
        }
        for (end, name) in refs {
            checked += 1;
            let Some((titles, numbers)) = docs.get(&name) else {
                problems.push(format!("{rel}: docs/{name} does not exist"));
                continue;
            };
            let rest = fold(&text[end..], 200);
            let rest = rest.strip_prefix(')').unwrap_or(&rest);
            let rest = rest.strip_prefix("'s").unwrap_or(rest).trim_start();
            let rest = rest.strip_prefix(',').unwrap_or(rest).trim_start();
            if let Some(after) = rest.strip_prefix('"') {
                let title = after.split('"').next().unwrap_or("");
                if !titles.iter().any(|t| t == title) {
                    problems.push(format!(
                        "{rel}: docs/{name} has no section titled {title:?}"
                    ));
                }
            } else if let Some(after) = rest.strip_prefix("section ") {
                let num: String = after
                    .chars()
                    .take_while(|c| c.is_ascii_digit() || *c == '.')
                    .collect();
                let num = num.trim_end_matches('.');
                if !numbers.iter().any(|n| n == num) {
                    problems.push(format!("{rel}: docs/{name} has no section {num}"));
                }
            }
        }
    }
    println!("{checked} references to docs/ checked");
    assert!(checked > 30, "only {checked} references found");
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// Top-level `const NAME: f64` / `usize` items of a source file, outside its
/// test module.
fn constants(path: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(path).expect("read source");
    let code = text.split("#[cfg(test)]").next().unwrap_or("");
    let mut out = Vec::new();
    for line in code.lines() {
        let l = line
            .trim_end()
            .trim_start_matches("pub(crate) ")
            .trim_start_matches("pub(super) ")
            .trim_start_matches("pub ");
        if let Some(rest) = l.strip_prefix("const ") {
            let name: String = rest
                .chars()
                .take_while(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || *c == '_')
                .collect();
            let ty = rest[name.len()..].trim_start_matches(':').trim_start();
            if !name.is_empty() && (ty.starts_with("f64") || ty.starts_with("usize")) {
                out.push(name);
            }
        }
    }
    out
}

#[test]
fn every_tolerance_is_documented() {
    let root = root();
    let docs = std::fs::read_to_string(root.join("docs/numerics.md")).unwrap()
        + &std::fs::read_to_string(root.join("docs/design.md")).unwrap();
    let mut files: Vec<PathBuf> = [
        "src/physics/decomp.rs",
        "src/physics/secular.rs",
        "src/physics/block.rs",
        "src/physics/hodlr.rs",
        "src/engine/exact.rs",
    ]
    .iter()
    .map(|f| root.join(f))
    .collect();
    for e in std::fs::read_dir(root.join("src/compile")).unwrap() {
        files.push(e.unwrap().path());
    }
    let mut missing = Vec::new();
    let mut n = 0;
    for f in &files {
        for c in constants(f) {
            n += 1;
            if !docs.contains(&format!("`{c}`")) && !docs.contains(&format!("`{c}`,")) {
                missing.push(format!("{} ({})", c, f.display()));
            }
        }
    }
    println!("{n} named tolerances, each in docs/numerics.md or docs/design.md");
    assert!(n >= 30, "only {n} constants found: the scan is broken");
    assert!(
        missing.is_empty(),
        "not in docs/numerics.md, \"Tolerances\":\n{}",
        missing.join("\n")
    );
}

/// The `crate::<module>` paths used by a source file's code (not its
/// comments or its test module).
fn crate_imports(text: &str) -> Vec<String> {
    let code = &text[..test_module_start(text)];
    let mut out = Vec::new();
    for line in code.lines() {
        let t = line.trim_start();
        if t.starts_with("//") {
            continue;
        }
        let t = t.split("//").next().unwrap_or("");
        for (i, _) in t.match_indices("crate::") {
            let name: String = t[i + 7..]
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            out.push(name);
        }
    }
    out
}

#[test]
fn the_layer_picture_matches_the_code() {
    let root = root();
    let design = std::fs::read_to_string(root.join("docs/design.md")).unwrap();
    let lib = std::fs::read_to_string(root.join("src/lib.rs")).unwrap();
    let modules: Vec<String> = lib
        .lines()
        .filter_map(|l| l.trim().strip_prefix("pub mod "))
        .map(|m| m.trim_end_matches(';').to_string())
        .filter(|m| m != "test_rng")
        .collect();
    // The picture: the first code block after the heading "Layers"; each
    // box row names its modules as the first word of a cell, top to bottom.
    let start = design
        .lines()
        .position(|l| l.starts_with("## ") && l.ends_with("Layers"))
        .map(|i| design.lines().take(i).map(|l| l.len() + 1).sum::<usize>())
        .expect("a Layers section");
    let block = design[start..].split("```").nth(1).expect("a picture");
    let mut level: BTreeMap<String, usize> = BTreeMap::new();
    let mut row = 0;
    for line in block.lines() {
        if line.trim_start().starts_with('+') {
            row += 1;
            continue;
        }
        if !line.trim_start().starts_with('|') {
            continue;
        }
        for cell in line.split('|') {
            if let Some(word) = cell.split_whitespace().next() {
                if modules.iter().any(|m| m == word) {
                    level.entry(word.to_string()).or_insert(row);
                }
            }
        }
    }
    for m in &modules {
        assert!(level.contains_key(m), "module {m} is not in the picture");
    }
    println!("layers (row from the top): {level:?}");
    // Every file of each module: no import of a module drawn above it.
    let mut upward = Vec::new();
    for m in &modules {
        let dir = root.join("src").join(m);
        let files: Vec<PathBuf> = if dir.is_dir() {
            // every .rs file under it, submodule folders included
            rs_files(&dir)
        } else {
            vec![root.join("src").join(format!("{m}.rs"))]
        };
        for f in files {
            if f.ends_with("tests.rs") {
                continue;
            }
            let text = std::fs::read_to_string(&f).unwrap();
            for used in crate_imports(&text) {
                if let (Some(&a), Some(&b)) = (level.get(m), level.get(&used)) {
                    if b < a {
                        upward.push(format!("{} uses crate::{used}", f.display()));
                    }
                }
            }
        }
    }
    assert!(
        upward.is_empty(),
        "imports running up the picture:\n{}",
        upward.join("\n")
    );
}

/// The lines of the first fenced code block after the line `heading` in
/// `text` (without the fences).
fn code_block_after<'a>(text: &[&'a str], heading: &str) -> Vec<&'a str> {
    let at = text
        .iter()
        .position(|l| *l == heading)
        .unwrap_or_else(|| panic!("no line {heading:?}"));
    let open = at
        + text[at..]
            .iter()
            .position(|l| l.starts_with("```"))
            .expect("a code block");
    let len = text[open + 1..]
        .iter()
        .position(|l| l.starts_with("```"))
        .expect("the block's end");
    text[open + 1..open + 1 + len].to_vec()
}

#[test]
fn readme_embedding_is_the_crate_doctest() {
    let root = root();
    let lib = std::fs::read_to_string(root.join("src/lib.rs")).unwrap();
    let doc: Vec<&str> = lib
        .lines()
        .filter_map(|l| l.strip_prefix("//!"))
        .map(|l| l.strip_prefix(' ').unwrap_or(l))
        .collect();
    // what rustdoc shows of the doctest: its hidden `# ` lines left out
    let shown: Vec<&str> = code_block_after(&doc, "# Embedding")
        .into_iter()
        .filter(|l| !(*l == "#" || l.starts_with("# ")))
        .collect();
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let readme: Vec<&str> = readme.lines().collect();
    let snippet = code_block_after(&readme, "## Embedding");
    assert!(shown.len() > 5, "the crate doc's example: {shown:?}");
    assert_eq!(
        snippet, shown,
        "README.md, \"Embedding\", is not the example of src/lib.rs, \"Embedding\""
    );
}

/// Every file of `tests/` is built and run by exactly one test binary: the
/// package sets `autotests = false` (a few binaries link faster than one per
/// file), so a file that is neither a `[[test]]` of Cargo.toml nor included
/// by one (`#[path = "stability.rs"] mod stability;`) would never run.
#[test]
fn every_test_file_is_in_one_test_binary() {
    let root = root();
    let manifest: toml::Table = std::fs::read_to_string(root.join("Cargo.toml"))
        .unwrap()
        .parse()
        .expect("Cargo.toml parses");
    let package = manifest["package"].as_table().expect("[package]");
    assert_eq!(
        package.get("autotests").and_then(|v| v.as_bool()),
        Some(false),
        "Cargo.toml's [package] sets autotests = false (the [[test]] targets list the binaries)"
    );
    let targets = manifest
        .get("test")
        .and_then(|t| t.as_array())
        .expect("[[test]] targets in Cargo.toml");
    // file of tests/ -> the binaries that build it
    let mut built: BTreeMap<String, Vec<String>> = BTreeMap::new();
    let mut problems = Vec::new();
    for t in targets {
        let name = t.get("name").and_then(|n| n.as_str()).expect("a name");
        let Some(path) = t.get("path").and_then(|p| p.as_str()) else {
            problems.push(format!("[[test]] {name} has no path"));
            continue;
        };
        let Some(file) = path.strip_prefix("tests/") else {
            problems.push(format!("[[test]] {name}: {path} is not in tests/"));
            continue;
        };
        built.entry(file.into()).or_default().push(name.into());
        let Ok(text) = std::fs::read_to_string(root.join(path)) else {
            problems.push(format!("[[test]] {name}: {path} does not exist"));
            continue;
        };
        for line in text.lines() {
            if let Some(rest) = line.trim().strip_prefix("#[path = \"") {
                let included = rest.split('"').next().unwrap_or("");
                built.entry(included.into()).or_default().push(name.into());
            }
        }
    }
    let mut files = Vec::new();
    for e in std::fs::read_dir(root.join("tests")).unwrap() {
        let p = e.unwrap().path();
        if p.is_file() && p.extension().is_some_and(|x| x == "rs") {
            files.push(p.file_name().unwrap().to_string_lossy().into_owned());
        }
    }
    files.sort();
    for f in &files {
        match built.get(f).map(Vec::as_slice) {
            None | Some([]) => problems.push(format!(
                "tests/{f} is in no test binary: include it in a harness of \
                 Cargo.toml's [[test]] targets (`#[path = \"{f}\"] mod ...;`)"
            )),
            Some([_]) => {}
            Some(more) => problems.push(format!("tests/{f} is in several binaries: {more:?}")),
        }
    }
    for f in built.keys() {
        if !files.contains(f) {
            problems.push(format!(
                "tests/{f} is named by Cargo.toml or a harness but does not exist"
            ));
        }
    }
    println!(
        "{} files of tests/ in {} test binaries",
        files.len(),
        targets.len()
    );
    assert!(
        files.len() > 20,
        "only {} files found: the scan is broken",
        files.len()
    );
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// Where a source file's test module starts (the `#[cfg(test)]` before its
/// first `mod`; a `#[cfg(test)]` item before it is code), or its end.
fn test_module_start(text: &str) -> usize {
    text.match_indices("#[cfg(test)]")
        .find(|(i, m)| text[i + m.len()..].trim_start().starts_with("mod "))
        .map_or(text.len(), |(i, _)| i)
}

/// The code of a source file without comments, string contents and its
/// test module (from the `#[cfg(test)]` of the first `mod`).
fn code_only(text: &str) -> String {
    let end = test_module_start(text);
    let mut out = String::new();
    for line in text[..end].lines() {
        let t = line.split("//").next().unwrap_or("");
        // string literals hold no paths to count
        let mut in_str = false;
        for c in t.chars() {
            if c == '"' {
                in_str = !in_str;
                continue;
            }
            if !in_str {
                out.push(c);
            }
        }
        out.push('\n');
    }
    out
}

/// Every `.rs` file under `dir`, subfolders included.
fn rs_files(dir: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "rs") {
                files.push(p);
            }
        }
    }
    files
}

/// The module path of every `.rs` file under `src` (`src/lib.rs` or
/// `src/main.rs` is the root `[]`, `a/mod.rs` and `a.rs` are `[a]`,
/// `a/b.rs` is `[a, b]`).
fn module_files(src: &Path) -> BTreeMap<Vec<String>, PathBuf> {
    let mut out = BTreeMap::new();
    for p in rs_files(src) {
        let rel = p.strip_prefix(src).unwrap();
        let mut m: Vec<String> = rel
            .with_extension("")
            .components()
            .map(|c| c.as_os_str().to_string_lossy().into_owned())
            .collect();
        if matches!(m.last().map(String::as_str), Some("mod" | "lib" | "main")) {
            m.pop();
        }
        if rel.starts_with("bin") {
            continue;
        }
        out.insert(m, p);
    }
    out
}

/// The paths a file's code names, each as the segments after the file's
/// own module is resolved (`crate::a::b`, `super::a`, `self::a`, and a
/// child module named at the start of a `use`), one brace group deep.
fn named_paths(code: &str, module: &[String], children: &[String]) -> Vec<Vec<String>> {
    let ident = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect()
    };
    let mut out = Vec::new();
    let bytes: Vec<char> = code.chars().collect();
    let text: String = bytes.iter().collect();
    let mut starts: Vec<(usize, Vec<String>)> = Vec::new();
    for (i, _) in text.match_indices("crate::") {
        starts.push((i + 7, Vec::new()));
    }
    for (i, _) in text.match_indices("super::") {
        // count the chain of `super::`
        if i >= 7 && &text[i - 7..i] == "super::" {
            continue;
        }
        let mut base = module.to_vec();
        let mut j = i;
        while text[j..].starts_with("super::") {
            base.pop();
            j += 7;
        }
        starts.push((j, base));
    }
    for (i, _) in text.match_indices("self::") {
        if i >= 2 && &text[i - 2..i] == "::" {
            continue;
        }
        starts.push((i + 6, module.to_vec()));
    }
    for (i, _) in text.match_indices("use ") {
        let rest = &text[i + 4..];
        let first = ident(rest);
        if children.contains(&first) {
            starts.push((i + 4, module.to_vec()));
        }
    }
    for (at, base) in starts {
        let rest = &text[at..];
        if let Some(group) = rest.strip_prefix('{') {
            // one brace group: each item's leading segments
            let mut depth = 0;
            let mut item = String::new();
            for c in group.chars() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 0 => break,
                    '}' => depth -= 1,
                    ',' if depth == 0 => {
                        let mut p = base.clone();
                        p.extend(item.trim().split("::").map(ident).filter(|s| !s.is_empty()));
                        out.push(p);
                        item.clear();
                        continue;
                    }
                    _ => {}
                }
                item.push(c);
            }
            let mut p = base.clone();
            p.extend(item.trim().split("::").map(ident).filter(|s| !s.is_empty()));
            out.push(p);
            continue;
        }
        let mut p = base.clone();
        let mut r = rest;
        loop {
            let id = ident(r);
            if id.is_empty() {
                break;
            }
            r = &r[id.len()..];
            p.push(id);
            match r.strip_prefix("::") {
                Some(t) if !t.starts_with('{') => r = t,
                _ => break,
            }
        }
        out.push(p);
    }
    out
}

/// File -> files whose items it names, between files of which neither is
/// the other's module ancestor (a module's file and its own submodules'
/// files are one room: a parent declares its children, children use
/// their parent's items).
fn file_graph(src: &Path) -> BTreeMap<PathBuf, BTreeSet<PathBuf>> {
    let files = module_files(src);
    let mut graph: BTreeMap<PathBuf, BTreeSet<PathBuf>> = BTreeMap::new();
    for (m, f) in &files {
        let text = std::fs::read_to_string(f).unwrap();
        let code = code_only(&text);
        let children: Vec<String> = files
            .keys()
            .filter(|k| k.len() == m.len() + 1 && k.starts_with(m))
            .map(|k| k.last().unwrap().clone())
            .collect();
        let edges = graph.entry(f.clone()).or_default();
        for p in named_paths(&code, m, &children) {
            // the longest prefix that is a module file
            let Some(target) = (1..=p.len())
                .rev()
                .map(|n| &p[..n])
                .find(|q| files.contains_key(*q))
            else {
                continue;
            };
            if target.starts_with(m) || m.starts_with(target) {
                continue;
            }
            edges.insert(files[target].clone());
        }
    }
    graph
}

/// The cycles of a file graph (each once, as the files of one strongly
/// connected component with more than one file).
fn cycles(graph: &BTreeMap<PathBuf, BTreeSet<PathBuf>>) -> Vec<Vec<PathBuf>> {
    // Tarjan's strongly connected components, recursive (small graphs)
    struct T<'a> {
        g: &'a BTreeMap<PathBuf, BTreeSet<PathBuf>>,
        index: BTreeMap<&'a PathBuf, usize>,
        low: BTreeMap<&'a PathBuf, usize>,
        stack: Vec<&'a PathBuf>,
        on: BTreeSet<&'a PathBuf>,
        out: Vec<Vec<PathBuf>>,
    }
    fn visit<'a>(t: &mut T<'a>, v: &'a PathBuf) {
        let i = t.index.len();
        t.index.insert(v, i);
        t.low.insert(v, i);
        t.stack.push(v);
        t.on.insert(v);
        if let Some(ws) = t.g.get(v) {
            for w in ws {
                let Some((w, _)) = t.g.get_key_value(w) else {
                    continue;
                };
                if !t.index.contains_key(w) {
                    visit(t, w);
                    let lw = t.low[w];
                    let lv = t.low.get_mut(v).unwrap();
                    *lv = (*lv).min(lw);
                } else if t.on.contains(w) {
                    let iw = t.index[w];
                    let lv = t.low.get_mut(v).unwrap();
                    *lv = (*lv).min(iw);
                }
            }
        }
        if t.low[v] == t.index[v] {
            let mut comp = Vec::new();
            while let Some(w) = t.stack.pop() {
                t.on.remove(w);
                comp.push(w.clone());
                if w == v {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                t.out.push(comp);
            }
        }
    }
    let mut t = T {
        g: graph,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in graph.keys() {
        if !t.index.contains_key(v) {
            visit(&mut t, v);
        }
    }
    t.out
}

/// docs/design.md, "Layers": no two files import each other, directly or
/// around a circle, in the plugin crate and in xtask (a module's file and
/// its own submodules' files count as one).
#[test]
fn no_file_imports_a_file_that_imports_it() {
    let root = root();
    let mut found = Vec::new();
    for src in ["src", "xtask/src"] {
        let graph = file_graph(&root.join(src));
        let edges: usize = graph.values().map(BTreeSet::len).sum();
        println!("{src}: {} files, {edges} imports between them", graph.len());
        assert!(
            edges > 10,
            "{src}: the import reader found only {edges} imports"
        );
        for c in cycles(&graph) {
            found.push(
                c.iter()
                    .map(|p| p.strip_prefix(&root).unwrap().display().to_string())
                    .collect::<Vec<_>>()
                    .join(" <-> "),
            );
        }
    }
    assert!(found.is_empty(), "import cycles:\n{}", found.join("\n"));
}
