//! The dependencies between the top-level modules of the library (`docs/architecture.md`).
//!
//! Every `src/**/*.rs` file belongs to a top-level module (`src/foo.rs` and `src/foo/**` to
//! `foo`; `src/lib.rs` and `src/main.rs` to none). Its dependencies are the first path segments
//! after `crate::` (in `use` lines, grouped imports `crate::{a::X, b::Y}` and inline paths) and
//! after as many `super::` as lead out of the top-level module. Comments, string and character
//! literals are not read, nor test code: from the first `#[cfg(test)]` of a file to its end
//! (unit test modules sit at the end of files), except that `#[cfg(test)] mod name;` leaves out
//! only the file it names (a test-only module in its own file).
//!
//! The tests check that the module graph has no cycle, that every dependency goes down the
//! layers below (or is one of the few allowed within a layer), and that the files of one folder
//! do not depend on each other in a cycle. `cargo test --test architecture
//! -- --nocapture` also prints the graph and the longest function of every module.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The layers, lowest first: a module may use the modules of lower layers, and those of its own
/// layer only as listed in [`SAME_LAYER`].
const LAYERS: &[&[&str]] = &[
    &["units", "algebra"],
    &["mesh", "fem", "material", "waveform", "analytic"],
    &["element", "solve"],
    &["problem"],
    &["time"],
    &["job"],
    &["io"],
    &["adjoint", "calibrate", "control"],
    &["lumped", "api"],
    &["cli"],
];

/// The allowed dependencies (user, used) within a layer.
const SAME_LAYER: &[(&str, &str)] = &[
    ("fem", "mesh"),
    ("fem", "material"),
    ("analytic", "material"),
];

/// One source file, as read for these checks.
struct Source {
    /// Path relative to the crate (`src/io/output.rs`).
    rel: String,
    /// Top-level module.
    module: String,
    /// The code with comments and the contents of literals blanked (newlines kept, so line
    /// numbers hold) and its test code cut off.
    code: String,
}

/// A use of another top-level module.
struct Dep {
    from: String,
    to: String,
    file: String,
    line: usize,
}

fn is_ident(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// At a raw string `r"`, `r#"`, `br#"`…: the index after its `r` and that of its opening quote.
fn raw_string_at(c: &[char], i: usize, prev_ident: bool) -> Option<(usize, usize)> {
    if prev_ident {
        return None;
    }
    let start = match (c[i], c.get(i + 1)) {
        ('r', _) => i + 1,
        ('b', Some('r')) => i + 2,
        _ => return None,
    };
    let mut j = start;
    while c.get(j) == Some(&'#') {
        j += 1;
    }
    (c.get(j) == Some(&'"')).then_some((start, j))
}

/// `src` with comments and the contents of string and character literals replaced by spaces
/// (newlines are kept). Knows `//`, nested `/* */`, `"…"` with escapes, raw strings `r#"…"#`,
/// byte strings, and tells character literals from lifetimes.
fn strip(src: &str) -> String {
    let c: Vec<char> = src.chars().collect();
    let mut out = String::with_capacity(src.len());
    let blank = |out: &mut String, ch: char| out.push(if ch == '\n' { '\n' } else { ' ' });
    let mut i = 0;
    while i < c.len() {
        let prev_ident = i > 0 && is_ident(c[i - 1]);
        if c[i] == '/' && c.get(i + 1) == Some(&'/') {
            while i < c.len() && c[i] != '\n' {
                out.push(' ');
                i += 1;
            }
        } else if c[i] == '/' && c.get(i + 1) == Some(&'*') {
            let mut depth = 0;
            while i < c.len() {
                if c[i] == '/' && c.get(i + 1) == Some(&'*') {
                    depth += 1;
                    out.push_str("  ");
                    i += 2;
                } else if c[i] == '*' && c.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    out.push_str("  ");
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    blank(&mut out, c[i]);
                    i += 1;
                }
            }
        } else if let Some((start, j)) = raw_string_at(&c, i, prev_ident) {
            let hashes = j - start;
            for &ch in &c[i..=j] {
                out.push(ch);
            }
            i = j + 1;
            while i < c.len() {
                if c[i] == '"' && (1..=hashes).all(|k| c.get(i + k) == Some(&'#')) {
                    for &ch in &c[i..=i + hashes] {
                        out.push(ch);
                    }
                    i += hashes + 1;
                    break;
                }
                blank(&mut out, c[i]);
                i += 1;
            }
        } else if c[i] == '"' {
            out.push('"');
            i += 1;
            while i < c.len() {
                if c[i] == '\\' {
                    blank(&mut out, c[i]);
                    i += 1;
                    if i < c.len() {
                        blank(&mut out, c[i]);
                        i += 1;
                    }
                } else if c[i] == '"' {
                    out.push('"');
                    i += 1;
                    break;
                } else {
                    blank(&mut out, c[i]);
                    i += 1;
                }
            }
        } else if c[i] == '\'' {
            // a character literal ('x', '\n', '\u{…}', '"') or a lifetime / label ('a)
            let end = if c.get(i + 1) == Some(&'\\') {
                (i + 3..c.len()).find(|&j| c[j] == '\'')
            } else if c.get(i + 2) == Some(&'\'') {
                Some(i + 2)
            } else {
                None
            };
            match end {
                Some(e) => {
                    out.push('\'');
                    for &ch in &c[i + 1..e] {
                        blank(&mut out, ch);
                    }
                    out.push('\'');
                    i = e + 1;
                }
                None => {
                    out.push('\'');
                    i += 1;
                }
            }
        } else {
            out.push(c[i]);
            i += 1;
        }
    }
    out
}

/// The top-level module of a path relative to `src/` (`None` for `lib.rs`, `main.rs`).
fn top_module(rel: &Path) -> Option<String> {
    let mut parts = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned());
    let first = parts.next()?;
    if parts.next().is_some() {
        return Some(first);
    }
    let stem = first.strip_suffix(".rs")?;
    (stem != "lib" && stem != "main").then(|| stem.to_string())
}

/// Every `.rs` file under `dir`, sorted.
fn rust_files(dir: &Path, files: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("directory entry").path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            rust_files(&p, files);
        } else if p.extension().is_some_and(|e| e == "rs") {
            files.push(p);
        }
    }
}

/// The module path of a file relative to `src/` (`io/output.rs` → [io, output]; `io/mod.rs` →
/// [io]).
fn module_path(rel: &Path) -> Vec<String> {
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    let last = parts.pop().unwrap_or_default();
    let stem = last.trim_end_matches(".rs");
    if stem != "mod" && stem != "lib" && stem != "main" {
        parts.push(stem.to_string());
    }
    parts
}

/// Cuts the test code off a stripped file: from the first `#[cfg(test)]` to the end, except a
/// `#[cfg(test)] mod name;` (blanked, and the file it names returned as test-only).
fn cut_tests(code: &str) -> (String, Vec<String>) {
    let mut kept: Vec<String> = Vec::new();
    let mut test_files = Vec::new();
    let lines: Vec<&str> = code.lines().collect();
    let mut i = 0;
    while i < lines.len() {
        let line = lines[i].trim();
        if let Some(rest) = line.strip_prefix("#[cfg(test)]") {
            // the item: rest of this line, or the next non-empty line
            let rest = rest.trim();
            let (item, item_line) = if rest.is_empty() {
                match (i + 1..lines.len()).find(|&j| !lines[j].trim().is_empty()) {
                    Some(j) => (lines[j].trim(), j),
                    None => ("", i),
                }
            } else {
                (rest, i)
            };
            let decl = item
                .strip_prefix("pub(crate) ")
                .or_else(|| item.strip_prefix("pub "))
                .unwrap_or(item)
                .strip_prefix("mod ")
                .and_then(|m| m.trim().strip_suffix(';'))
                .map(str::trim);
            match decl {
                Some(name) if name.chars().all(is_ident) => {
                    test_files.push(name.to_string());
                    for _ in i..=item_line {
                        kept.push(String::new());
                    }
                    i = item_line + 1;
                    continue;
                }
                _ => break,
            }
        }
        kept.push(lines[i].to_string());
        i += 1;
    }
    (kept.join("\n"), test_files)
}

/// Reads every source file of the crate.
fn sources() -> Vec<Source> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let src = root.join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut read = Vec::new();
    let mut test_only: BTreeSet<PathBuf> = BTreeSet::new();
    for path in &files {
        let rel = path.strip_prefix(&src).expect("under src/").to_path_buf();
        let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path:?}: {e}"));
        let (code, tests) = cut_tests(&strip(&text));
        // `mod name;` in dir/mod.rs or dir.rs names dir/name.rs or dir/name/mod.rs
        let dir = src.join(module_path(&rel).iter().collect::<PathBuf>());
        for t in tests {
            test_only.insert(dir.join(format!("{t}.rs")));
            test_only.insert(dir.join(&t));
        }
        read.push((path.clone(), rel, code));
    }
    read.into_iter()
        .filter(|(path, _, _)| !test_only.iter().any(|t| path.starts_with(t)))
        .filter_map(|(_, rel, code)| {
            Some(Source {
                module: top_module(&rel)?,
                rel: format!("src/{}", rel.display()),
                code,
            })
        })
        .collect()
}

/// The identifier at `c[i..]` (skipping whitespace before it).
fn ident_at(c: &[char], mut i: usize) -> (String, usize) {
    while i < c.len() && c[i].is_whitespace() {
        i += 1;
    }
    let start = i;
    while i < c.len() && is_ident(c[i]) {
        i += 1;
    }
    (c[start..i].iter().collect(), i)
}

/// The 1-based line of every character of `c`.
fn line_numbers(c: &[char]) -> Vec<usize> {
    let mut line_of = Vec::with_capacity(c.len());
    let mut line = 1;
    for &ch in c {
        line_of.push(line);
        if ch == '\n' {
            line += 1;
        }
    }
    line_of
}

/// Whether `s` stands in `c` at `i`.
fn starts_at(c: &[char], i: usize, s: &str) -> bool {
    s.chars()
        .enumerate()
        .all(|(k, ch)| c.get(i + k) == Some(&ch))
}

/// The top-level modules a file's code refers to, with the line of each reference.
fn references(source: &Source) -> Vec<(String, usize)> {
    let c: Vec<char> = source.code.chars().collect();
    let depth = module_path(Path::new(source.rel.trim_start_matches("src/"))).len();
    let line_of = line_numbers(&c);
    let starts_with = |i: usize, s: &str| starts_at(&c, i, s);
    let mut refs = Vec::new();
    let mut i = 0;
    while i < c.len() {
        let boundary = i == 0 || !is_ident(c[i - 1]);
        if boundary && starts_with(i, "crate::") {
            let mut j = i + "crate::".len();
            while j < c.len() && c[j].is_whitespace() {
                j += 1;
            }
            if c.get(j) == Some(&'{') {
                // crate::{a::X, b::{Y, Z}}: the first segment of every top-level item
                let mut nest = 0;
                let mut expect_item = true;
                j += 1;
                while j < c.len() {
                    match c[j] {
                        '{' => nest += 1,
                        '}' if nest == 0 => break,
                        '}' => nest -= 1,
                        ',' if nest == 0 => expect_item = true,
                        ch if expect_item && is_ident(ch) => {
                            let (name, end) = ident_at(&c, j);
                            refs.push((name, line_of[j]));
                            expect_item = false;
                            j = end;
                            continue;
                        }
                        _ => {}
                    }
                    j += 1;
                }
            } else {
                let (name, end) = ident_at(&c, j);
                if !name.is_empty() {
                    refs.push((name, line_of[i]));
                }
                j = end;
            }
            i = j.max(i + 1);
        } else if boundary && starts_with(i, "super::") {
            // super::super::x leading out of the top-level module names the module x
            let mut j = i;
            let mut ups = 0;
            while starts_with(j, "super::") {
                ups += 1;
                j += "super::".len();
            }
            if ups >= depth {
                let (name, _) = ident_at(&c, j);
                if !name.is_empty() {
                    refs.push((name, line_of[i]));
                }
            }
            i = j;
        } else {
            i += 1;
        }
    }
    refs
}

/// Every use of another top-level module.
fn dependencies(sources: &[Source]) -> Vec<Dep> {
    let mut deps = Vec::new();
    for s in sources {
        for (to, line) in references(s) {
            if to != s.module && to != "self" && to != "super" && to != "crate" {
                deps.push(Dep {
                    from: s.module.clone(),
                    to,
                    file: s.rel.clone(),
                    line,
                });
            }
        }
    }
    deps
}

/// module → (used module → its uses as `file:line`).
type Graph = BTreeMap<String, BTreeMap<String, Vec<String>>>;

fn graph(sources: &[Source], deps: &[Dep]) -> Graph {
    let mut g: Graph = BTreeMap::new();
    for s in sources {
        g.entry(s.module.clone()).or_default();
    }
    for d in deps {
        g.entry(d.from.clone())
            .or_default()
            .entry(d.to.clone())
            .or_default()
            .push(format!("{}:{}", d.file, d.line));
    }
    g
}

fn layer_of(module: &str) -> Option<usize> {
    LAYERS.iter().position(|l| l.contains(&module))
}

/// Every cycle found by a depth-first search (one per back edge), as module paths.
fn cycles(g: &Graph) -> Vec<Vec<String>> {
    fn visit(
        m: &str,
        g: &Graph,
        state: &mut BTreeMap<String, u8>,
        stack: &mut Vec<String>,
        found: &mut Vec<Vec<String>>,
    ) {
        state.insert(m.to_string(), 1);
        stack.push(m.to_string());
        for next in g.get(m).into_iter().flat_map(|e| e.keys()) {
            match state.get(next.as_str()).copied().unwrap_or(0) {
                0 => visit(next, g, state, stack, found),
                1 => {
                    let at = stack.iter().position(|s| s == next).expect("on the stack");
                    let mut cycle = stack[at..].to_vec();
                    cycle.push(next.clone());
                    found.push(cycle);
                }
                _ => {}
            }
        }
        stack.pop();
        state.insert(m.to_string(), 2);
    }
    let mut state = BTreeMap::new();
    let mut found = Vec::new();
    for m in g.keys() {
        if !state.contains_key(m.as_str()) {
            visit(m, g, &mut state, &mut Vec::new(), &mut found);
        }
    }
    found
}

/// The first uses of `to` by `from`, for messages.
fn examples(g: &Graph, from: &str, to: &str) -> String {
    let uses = &g[from][to];
    let shown: Vec<&str> = uses.iter().take(3).map(String::as_str).collect();
    let more = if uses.len() > 3 {
        format!(" and {} more", uses.len() - 3)
    } else {
        String::new()
    };
    format!("{}{more}", shown.join(", "))
}

#[test]
fn no_cycle_between_top_level_modules() {
    let sources = sources();
    let g = graph(&sources, &dependencies(&sources));
    let found = cycles(&g);
    let mut msg = String::new();
    for cycle in &found {
        msg.push_str(&format!("cycle: {}\n", cycle.join(" -> ")));
        for w in cycle.windows(2) {
            msg.push_str(&format!(
                "  {} -> {}: {}\n",
                w[0],
                w[1],
                examples(&g, &w[0], &w[1])
            ));
        }
    }
    assert!(
        found.is_empty(),
        "the top-level modules depend on each other in a cycle:\n{msg}"
    );
}

#[test]
fn dependencies_follow_the_layers() {
    let sources = sources();
    let g = graph(&sources, &dependencies(&sources));
    let mut problems = Vec::new();
    let mut unknown = BTreeSet::new();
    for (from, uses) in &g {
        let Some(lf) = layer_of(from) else {
            unknown.insert(from.clone());
            continue;
        };
        for to in uses.keys() {
            let Some(lt) = layer_of(to) else {
                unknown.insert(to.clone());
                continue;
            };
            let allowed =
                lt < lf || (lt == lf && SAME_LAYER.contains(&(from.as_str(), to.as_str())));
            if !allowed {
                let why = if lt == lf {
                    "same layer, not an allowed pair"
                } else {
                    "upwards"
                };
                problems.push(format!(
                    "{from} (layer {lf}) uses {to} (layer {lt}; {why}): {}",
                    examples(&g, from, to)
                ));
            }
        }
    }
    for m in &unknown {
        problems.push(format!(
            "`{m}` is a top-level module that the layering does not know: add it to LAYERS in \
             tests/architecture.rs (and to docs/architecture.md)"
        ));
    }
    assert!(
        problems.is_empty(),
        "module dependencies that break the layering (units, algebra → mesh, fem, material, \
         waveform, analytic → element, solve → problem → time → job → io → lumped → cli):\n  {}",
        problems.join("\n  ")
    );
}

/// The functions of a stripped source: (name, first line, line count). Finds `fn NAME`, the
/// first `{` after it outside parentheses and brackets (a `;` first means no body) and its
/// matching `}`. Approximate: literals are blanked by [`strip`], but macros that expand to
/// functions are not seen, and a nested function is counted in its parent too.
fn functions(code: &str) -> Vec<(String, usize, usize)> {
    let c: Vec<char> = code.chars().collect();
    let line_of = line_numbers(&c);
    let mut found = Vec::new();
    let mut i = 0;
    while i + 2 < c.len() {
        let boundary = i == 0 || !is_ident(c[i - 1]);
        if !(boundary && c[i] == 'f' && c[i + 1] == 'n' && c[i + 2].is_whitespace()) {
            i += 1;
            continue;
        }
        let (name, mut j) = ident_at(&c, i + 2);
        if name.is_empty() {
            i += 2;
            continue;
        }
        let mut paren = 0i32;
        let mut body = None;
        while j < c.len() {
            match c[j] {
                '(' | '[' => paren += 1,
                ')' | ']' => paren -= 1,
                ';' if paren == 0 => break,
                '{' if paren == 0 => {
                    body = Some(j);
                    break;
                }
                _ => {}
            }
            j += 1;
        }
        if let Some(open) = body {
            let mut depth = 0;
            let mut k = open;
            while k < c.len() {
                match c[k] {
                    '{' => depth += 1,
                    '}' => {
                        depth -= 1;
                        if depth == 0 {
                            break;
                        }
                    }
                    _ => {}
                }
                k += 1;
            }
            let end = line_of[k.min(c.len() - 1)];
            found.push((name, line_of[i], end - line_of[i] + 1));
        }
        i += 2;
    }
    found
}

/// Prints the module graph and the longest function of each module (a report; run with
/// `--nocapture` to see it).
#[test]
fn report_module_graph_and_longest_functions() {
    let sources = sources();
    let deps = dependencies(&sources);
    let g = graph(&sources, &deps);
    let mut order: Vec<&String> = g.keys().collect();
    order.sort_by_key(|m| (layer_of(m).unwrap_or(usize::MAX), m.to_string()));
    println!("module graph (layer: module -> used modules, with the number of references):");
    for m in &order {
        let layer = layer_of(m).map_or("?".to_string(), |l| l.to_string());
        let uses: Vec<String> = g[*m]
            .iter()
            .map(|(to, at)| format!("{to} ({})", at.len()))
            .collect();
        let uses = if uses.is_empty() {
            "-".to_string()
        } else {
            uses.join(", ")
        };
        println!("  {layer}: {m} -> {uses}");
    }
    println!(
        "longest function of each module (lines from `fn` to its closing brace, approximate):"
    );
    for m in &order {
        let longest = sources
            .iter()
            .filter(|s| &&s.module == m)
            .flat_map(|s| {
                functions(&s.code)
                    .into_iter()
                    .map(move |(name, line, n)| (n, name, s.rel.clone(), line))
            })
            .max_by(|a, b| a.0.cmp(&b.0).then(b.2.cmp(&a.2)).then(b.3.cmp(&a.3)));
        match longest {
            Some((n, name, file, line)) => {
                println!("  {m:<9} {name} ({file}:{line}): {n} lines")
            }
            None => println!("  {m:<9} no function"),
        }
    }
}

/// The paths at `c[i..]` after a `crate::`, `super::` or `self::` head, as segment lists: a
/// group `a::{b::C, d::{E, F}}` gives `[a, b, C]`, `[a, d, E]`, `[a, d, F]`. Returns them and the
/// index after the path.
fn path_tree(c: &[char], mut i: usize) -> (Vec<Vec<String>>, usize) {
    let mut prefix = Vec::new();
    loop {
        while i < c.len() && c[i].is_whitespace() {
            i += 1;
        }
        if c.get(i) == Some(&'{') {
            let mut paths = Vec::new();
            i += 1;
            loop {
                while i < c.len() && (c[i].is_whitespace() || c[i] == ',') {
                    i += 1;
                }
                if i >= c.len() || c[i] == '}' {
                    return (paths, i + 1);
                }
                let (sub, next) = path_tree(c, i);
                if next <= i {
                    return (paths, i + 1);
                }
                for p in sub {
                    paths.push(prefix.iter().cloned().chain(p).collect());
                }
                i = next;
                // skip `as name`
                while i < c.len() && c[i] != ',' && c[i] != '}' {
                    i += 1;
                }
            }
        }
        let (name, end) = ident_at(c, i);
        if name.is_empty() {
            return (vec![prefix], i);
        }
        prefix.push(name);
        i = end;
        if c.get(i) == Some(&':') && c.get(i + 1) == Some(&':') {
            i += 2;
        } else {
            return (vec![prefix], i);
        }
    }
}

/// The files of the crate that a file's code refers to through module paths (`crate::a::b`,
/// `super::b`, `self::b`), each as its module path, with the line of the reference.
fn file_references(source: &Source, files: &BTreeSet<Vec<String>>) -> Vec<(Vec<String>, usize)> {
    let here = module_path(Path::new(source.rel.trim_start_matches("src/")));
    let c: Vec<char> = source.code.chars().collect();
    let line_of = line_numbers(&c);
    let starts_with = |i: usize, s: &str| starts_at(&c, i, s);
    let mut found = Vec::new();
    let mut i = 0;
    while i < c.len() {
        let boundary = i == 0 || !(is_ident(c[i - 1]) || c[i - 1] == ':');
        let head = ["crate::", "super::", "self::"]
            .into_iter()
            .find(|h| boundary && starts_with(i, h));
        let Some(head) = head else {
            i += 1;
            continue;
        };
        let mut base: Vec<String> = match head {
            "crate::" => Vec::new(),
            _ => here.clone(),
        };
        let mut j = i + head.len();
        if head == "super::" {
            base.pop();
            while starts_with(j, "super::") {
                base.pop();
                j += "super::".len();
            }
        }
        let (paths, end) = path_tree(&c, j);
        for p in paths {
            let full: Vec<String> = base.iter().cloned().chain(p).collect();
            // the longest prefix that is a file of the crate
            if let Some(k) = (1..=full.len()).rev().find(|&k| files.contains(&full[..k])) {
                found.push((full[..k].to_vec(), line_of[i]));
            }
        }
        i = end.max(i + 1);
    }
    found
}

/// Every cycle between the files of one folder (a folder's `mod.rs`, which declares the others,
/// is left out), as `file -> file -> ... -> file`, with the uses that tie each pair.
fn file_cycles(sources: &[Source]) -> Vec<String> {
    let files: BTreeSet<Vec<String>> = sources
        .iter()
        .map(|s| module_path(Path::new(s.rel.trim_start_matches("src/"))))
        .collect();
    let is_mod = |rel: &str| rel.ends_with("/mod.rs");
    let rel_of: BTreeMap<Vec<String>, String> = sources
        .iter()
        .map(|s| {
            (
                module_path(Path::new(s.rel.trim_start_matches("src/"))),
                s.rel.clone(),
            )
        })
        .collect();
    let mut g: Graph = BTreeMap::new();
    for s in sources.iter().filter(|s| !is_mod(&s.rel)) {
        let here = module_path(Path::new(s.rel.trim_start_matches("src/")));
        g.entry(s.rel.clone()).or_default();
        for (to, line) in file_references(s, &files) {
            let same_folder =
                to.len() == here.len() && to[..to.len() - 1] == here[..here.len() - 1];
            let to_rel = &rel_of[&to];
            if same_folder && to != here && !is_mod(to_rel) {
                g.entry(s.rel.clone())
                    .or_default()
                    .entry(to_rel.clone())
                    .or_default()
                    .push(format!("{}:{line}", s.rel));
            }
        }
    }
    cycles(&g)
        .into_iter()
        .map(|cycle| {
            let mut msg = cycle.join(" -> ");
            for w in cycle.windows(2) {
                msg.push_str(&format!(
                    "\n    {} -> {}: {}",
                    w[0],
                    w[1],
                    examples(&g, &w[0], &w[1])
                ));
            }
            msg
        })
        .collect()
}

#[test]
fn no_cycle_between_the_files_of_a_folder() {
    let found = file_cycles(&sources());
    assert!(
        found.is_empty(),
        "files of one folder depend on each other in a cycle (move the shared item into a file \
         of its own that both use):\n  {}",
        found.join("\n  ")
    );
}

/// The library prints nothing: outside the command line (`src/cli`, `src/main.rs`) no code
/// writes to stdout or stderr; it returns what it has to say, or reports it through the `log`
/// facade, which the command line prints.
#[test]
fn the_library_prints_nothing() {
    let mut found = Vec::new();
    for s in sources() {
        if s.rel.starts_with("src/cli/") || s.rel == "src/main.rs" {
            continue;
        }
        for (n, line) in s.code.lines().enumerate() {
            for m in ["println!", "eprintln!", "print!", "eprint!", "dbg!"] {
                let hit = line.match_indices(m).any(|(i, _)| {
                    i == 0 || !line[..i].ends_with(|c: char| c.is_alphanumeric() || c == '_')
                });
                if hit {
                    found.push(format!("{}:{}: {m}", s.rel, n + 1));
                }
            }
        }
    }
    assert!(
        found.is_empty(),
        "the library prints (return the message, or use log::warn!/log::info!):\n  {}",
        found.join("\n  ")
    );
}

#[test]
fn a_cycle_between_two_files_is_found() {
    let file = |rel: &str, text: &str| Source {
        rel: rel.into(),
        module: "job".into(),
        code: cut_tests(&strip(text)).0,
    };
    let a = file("src/job/a.rs", "use super::b::B;\npub struct A;");
    let b = file(
        "src/job/b.rs",
        "use crate::job::{a::A, c};\npub struct B; fn f() { crate::job::c::g() }",
    );
    let c = file("src/job/c.rs", "pub fn g() {}");
    let m = file(
        "src/job/mod.rs",
        "pub mod a; pub mod b; pub mod c; use self::a::A;",
    );
    let found = file_cycles(&[a, b, c, m]);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(found[0].starts_with("src/job/a.rs -> src/job/b.rs -> src/job/a.rs"));
    assert!(found[0].contains("src/job/b.rs:1"), "{}", found[0]);
    let a = file("src/job/a.rs", "pub struct A;");
    let b = file("src/job/b.rs", "use super::a::A; use super::super::io::x;");
    assert!(file_cycles(&[a, b]).is_empty());
}

#[test]
fn the_scanner_reads_paths_and_skips_comments_literals_and_tests() {
    let text = r####"use crate::mesh::Mesh; // crate::io in a comment
/// doc: crate::cli
use crate::{fem::X, material::{A, B}};
fn f<'a>(s: &'a str) -> char { let _ = "crate::job \" crate::lumped"; let _ = r#"crate::time"#; 'x' }
fn g() { crate::solve::go(); let c = '"'; let _ = crate::problem::P; }
/* crate::time /* nested */ crate::time */
#[cfg(test)]
mod more;
fn h() { super::waveform::w(); }
#[cfg(test)]
mod tests { use crate::cli; }
"####;
    let (code, test_files) = cut_tests(&strip(text));
    assert_eq!(test_files, vec!["more".to_string()]);
    let source = Source {
        rel: "src/element/x.rs".into(),
        module: "element".into(),
        code,
    };
    let refs: Vec<String> = references(&source).into_iter().map(|r| r.0).collect();
    assert_eq!(refs, ["mesh", "fem", "material", "solve", "problem"]);
    let top = Source {
        rel: "src/analytic.rs".into(),
        ..source
    };
    let refs: Vec<(String, usize)> = references(&top);
    assert_eq!(refs.last(), Some(&("waveform".to_string(), 9)));
    let fns: Vec<(String, usize, usize)> = functions(&top.code);
    assert_eq!(
        fns,
        [("f".into(), 4, 1), ("g".into(), 5, 1), ("h".into(), 9, 1)]
    );
}
