//! `docs/ARCHITECTURE.md` is true to the code and short enough to scan: every repository
//! path it names (in a code span, or as a link) exists; no paragraph or list item runs
//! past [`LONGEST_PARAGRAPH`] characters, nor the whole past [`LONGEST_DOCUMENT`]; and the
//! floors of its map are those the library's imports give — each top-level module one
//! floor above the highest module it uses as `crate::…` (unit tests aside), so that
//! imports run only downhill. Whatever is wrong is listed at once.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");
const DOCUMENT: &str = "docs/ARCHITECTURE.md";

/// The longest paragraph (or list item) the document may hold, in characters.
const LONGEST_PARAGRAPH: usize = 1200;

/// The longest the whole document may be, in characters.
const LONGEST_DOCUMENT: usize = 20_000;

/// Fewer distinct paths than this, and the test would pass on a document that names none.
const FEWEST_PATHS: usize = 30;

/// How a repository path in a code span starts.
const PREFIXES: [&str; 9] = [
    "src/",
    "tests/",
    "docs/",
    "examples/",
    "benches/",
    "python/",
    "fuzz/",
    "scripts/",
    ".ci/",
];

/// A top-level module's uses: each module it uses, with the first place it does.
type Uses = BTreeMap<String, BTreeMap<String, String>>;

fn read(path: &str) -> String {
    std::fs::read_to_string(Path::new(ROOT).join(path))
        .unwrap_or_else(|e| panic!("{path} is readable: {e}"))
}

/// The document's lines, those of fenced code blocks (and the fences) left blank.
fn prose(document: &str) -> Vec<&str> {
    let mut in_code = false;
    document
        .lines()
        .map(|line| {
            if line.starts_with("```") {
                in_code = !in_code;
                ""
            } else if in_code {
                ""
            } else {
                line
            }
        })
        .collect()
}

/// The paragraphs of the prose, each list item and table row on its own, as one line of
/// text with the line number where it starts.
fn paragraphs(lines: &[&str]) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut current: Option<(usize, String)> = None;
    for (i, line) in lines.iter().enumerate() {
        let text = line.trim();
        let numbered = text
            .split_once(". ")
            .is_some_and(|(n, _)| !n.is_empty() && n.chars().all(|c| c.is_ascii_digit()));
        let item = text.starts_with("- ") || text.starts_with("* ") || text.starts_with('|');
        if text.is_empty() || item || numbered {
            out.extend(current.take());
        }
        if text.is_empty() {
            continue;
        }
        match &mut current {
            Some((_, paragraph)) => {
                paragraph.push(' ');
                paragraph.push_str(text);
            }
            None => current = Some((i + 1, text.to_string())),
        }
    }
    out.extend(current);
    out
}

/// `path` without a trailing `:line` or `:line:column`.
fn without_line(mut path: &str) -> &str {
    for _ in 0..2 {
        match path.rsplit_once(':') {
            Some((head, tail)) if !tail.is_empty() && tail.chars().all(|c| c.is_ascii_digit()) => {
                path = head;
            }
            _ => break,
        }
    }
    path
}

/// The repository path a code span names, without a trailing `:line` or `#anchor`; `None`
/// for a span that is not one (a module's name, a type, a command line).
fn span_path(span: &str) -> Option<String> {
    let span = span.trim();
    if span.is_empty() || span.contains(char::is_whitespace) {
        return None;
    }
    let path = without_line(span.split('#').next().unwrap_or(span));
    let top_level_file = !path.contains('/')
        && path.starts_with(|c: char| c.is_ascii_uppercase())
        && [".md", ".toml", ".lock"].iter().any(|e| path.ends_with(e));
    (top_level_file || PREFIXES.iter().any(|p| path.starts_with(p))).then(|| path.to_string())
}

/// A relative link's target as a path from the repository's root: links are resolved
/// from `docs/`, where the document is.
fn link_path(target: &str) -> String {
    let mut parts: Vec<&str> = vec!["docs"];
    for part in target.split('/') {
        match part {
            "" | "." => {}
            ".." => {
                parts.pop();
            }
            _ => parts.push(part),
        }
    }
    parts.join("/")
}

/// Every path the prose names, with its line: the code spans that look like repository
/// paths, and the targets of relative links (outside code spans).
fn named_paths(lines: &[&str]) -> Vec<(usize, String)> {
    let text = lines.join("\n");
    let mut out = Vec::new();
    let mut line = 1;
    for (i, part) in text.split('`').enumerate() {
        if i % 2 == 1 {
            out.extend(span_path(part).map(|path| (line, path)));
        } else {
            let mut searched = 0;
            while let Some(at) = part[searched..].find("](") {
                let start = searched + at + 2;
                let Some(end) = part[start..].find(')') else {
                    break;
                };
                let target = part[start..start + end].trim();
                let local = !target.contains("://") && !target.starts_with("mailto:");
                let file = target.split('#').next().unwrap_or("");
                if local && !file.is_empty() {
                    out.push((line + part[..start].matches('\n').count(), link_path(file)));
                }
                searched = start + end;
            }
        }
        line += part.matches('\n').count();
    }
    out
}

#[test]
fn every_path_the_architecture_names_exists() {
    let text = read(DOCUMENT);
    let lines = prose(&text);
    assert_eq!(
        lines.join("\n").matches('`').count() % 2,
        0,
        "{DOCUMENT}: a code span is not closed"
    );
    let named = named_paths(&lines);
    let mut distinct: Vec<&str> = named.iter().map(|(_, path)| path.as_str()).collect();
    distinct.sort_unstable();
    distinct.dedup();
    assert!(
        distinct.len() >= FEWEST_PATHS,
        "{DOCUMENT} names {} paths, at least {FEWEST_PATHS} expected: {distinct:?}",
        distinct.len()
    );
    let missing: Vec<String> = named
        .iter()
        .filter(|(_, path)| !Path::new(ROOT).join(path).exists())
        .map(|(line, path)| format!("{DOCUMENT}:{line}: {path}"))
        .collect();
    assert!(
        missing.is_empty(),
        "paths {DOCUMENT} names that do not exist:\n{}",
        missing.join("\n")
    );
}

#[test]
fn the_architecture_is_short_enough_to_scan() {
    let text = read(DOCUMENT);
    let characters = text.chars().count();
    assert!(
        characters <= LONGEST_DOCUMENT,
        "{DOCUMENT} holds {characters} characters, at most {LONGEST_DOCUMENT} expected"
    );
    let long: Vec<String> = paragraphs(&prose(&text))
        .into_iter()
        .filter(|(_, paragraph)| paragraph.chars().count() > LONGEST_PARAGRAPH)
        .map(|(line, paragraph)| {
            let start: String = paragraph.chars().take(60).collect();
            format!(
                "{DOCUMENT}:{line}: {} characters: {start}…",
                paragraph.chars().count()
            )
        })
        .collect();
    assert!(
        long.is_empty(),
        "paragraphs over {LONGEST_PARAGRAPH} characters:\n{}",
        long.join("\n")
    );
}

#[test]
fn paths_and_paragraphs_are_read_as_written() {
    assert_eq!(
        span_path("src/solve/mod.rs:12"),
        Some("src/solve/mod.rs".into())
    );
    assert_eq!(span_path("README.md#python"), Some("README.md".into()));
    assert_eq!(span_path("src/cli/"), Some("src/cli/".into()));
    assert_eq!(span_path("solve"), None);
    assert_eq!(span_path("mod.rs"), None);
    assert_eq!(span_path("cargo test --test commands"), None);
    assert_eq!(link_path("../README.md"), "README.md");
    assert_eq!(link_path("FORMAT.md"), "docs/FORMAT.md");
    let text = "See `src/a.rs` and [b](../b.md#x),\n[c](#here), `d` and\n`tests/e/`.";
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(
        named_paths(&lines),
        vec![
            (1, "src/a.rs".to_string()),
            (1, "b.md".to_string()),
            (3, "tests/e/".to_string())
        ]
    );
    let text = "# T\n\nOne\ntwo.\n\n- a\n  b\n- c\n1. d\n";
    let lines: Vec<&str> = text.lines().collect();
    let found: Vec<String> = paragraphs(&lines).into_iter().map(|(_, p)| p).collect();
    assert_eq!(found, ["# T", "One two.", "- a b", "- c", "1. d"]);
}

/// The top-level modules of the library, as `src/lib.rs` declares them.
fn modules() -> Vec<String> {
    read("src/lib.rs")
        .lines()
        .filter_map(|line| line.trim().strip_prefix("pub mod ")?.strip_suffix(';'))
        .map(str::to_string)
        .collect()
}

/// The floors of the document's map: each `- **Floor N**` item of its section "The map",
/// with the modules it names in code spans.
fn map_floors(document: &str, modules: &[String]) -> BTreeMap<String, Vec<usize>> {
    let section = document
        .split("\n## ")
        .find(|section| section.starts_with("The map"))
        .unwrap_or_else(|| panic!("{DOCUMENT} has a section \"## The map\""));
    let mut floors: BTreeMap<String, Vec<usize>> = BTreeMap::new();
    let mut floor: Option<usize> = None;
    for line in section.lines() {
        let trimmed = line.trim_start();
        if trimmed.is_empty() || trimmed.starts_with("- ") {
            floor = trimmed.strip_prefix("- **Floor ").and_then(|rest| {
                let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
                digits.parse().ok()
            });
        }
        let Some(floor) = floor else { continue };
        for (i, span) in line.split('`').enumerate() {
            if i % 2 == 1 && modules.iter().any(|m| m == span) {
                let on = floors.entry(span.to_string()).or_default();
                if !on.contains(&floor) {
                    on.push(floor);
                }
            }
        }
    }
    floors
}

/// Every `.rs` file under `dir`.
fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("src is readable").flatten() {
        let path = entry.path();
        if path.is_dir() {
            sources(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The code of a source file, line by line with its number: comment lines, the end of a
/// line after `//` and the modules of unit tests (`#[cfg(test)]`, `#[cfg(all(test, …))]`)
/// left out.
fn code_lines(text: &str) -> Vec<(usize, &str)> {
    let mut out = Vec::new();
    let mut after_test_attribute = false;
    let mut in_test_module = false;
    for (i, line) in text.lines().enumerate() {
        let trimmed = line.trim();
        if in_test_module {
            in_test_module = line != "}";
            continue;
        }
        if trimmed.starts_with("//") || trimmed.is_empty() {
            continue;
        }
        if trimmed == "#[cfg(test)]" || trimmed.starts_with("#[cfg(all(test,") {
            after_test_attribute = true;
            continue;
        }
        if after_test_attribute {
            if trimmed.starts_with("#[") {
                continue;
            }
            after_test_attribute = false;
            if trimmed.contains("mod ") && trimmed.ends_with('{') {
                in_test_module = true;
                continue;
            }
            if trimmed.contains("mod ") && trimmed.ends_with(';') {
                continue;
            }
        }
        // a comment at the end of the line, where no string is open
        let code = match line.find("//") {
            Some(at) if line[..at].matches('"').count() % 2 == 0 => &line[..at],
            _ => line,
        };
        out.push((i + 1, code));
    }
    out
}

/// The top-level modules named by the path that follows a `crate::`: `NAME…`, or each
/// item of a `{…}` group.
fn modules_after(rest: &str, modules: &[String]) -> Vec<String> {
    let ident = |s: &str| -> String {
        s.trim_start()
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect()
    };
    let names = match rest.strip_prefix('{') {
        Some(group) => {
            let mut names = vec![ident(group)];
            let mut depth = 1;
            for (i, c) in group.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' => depth -= 1,
                    ',' if depth == 1 => names.push(ident(&group[i + 1..])),
                    _ => {}
                }
                if depth == 0 {
                    break;
                }
            }
            names
        }
        None => vec![ident(rest)],
    };
    names
        .into_iter()
        .filter(|name| modules.contains(name))
        .collect()
}

/// Which modules each top-level module uses (its unit tests aside), and the places where
/// a file leaves its top-level module through `super::` rather than `crate::`.
fn imports(modules: &[String]) -> (Uses, Vec<String>) {
    let src = Path::new(ROOT).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    files.sort();
    assert!(files.len() > 50, "the sources were found: {}", files.len());
    let mut uses = Uses::new();
    let mut escapes = Vec::new();
    for file in &files {
        let relative = file.strip_prefix(&src).expect("under src");
        let parts: Vec<String> = relative
            .iter()
            .map(|part| part.to_string_lossy().into_owned())
            .collect();
        let top = parts[0].trim_end_matches(".rs").to_string();
        let last = parts.last().map(String::as_str);
        if !modules.contains(&top) || last == Some("tests.rs") {
            continue;
        }
        // src/a.rs and src/a/mod.rs are module a, one deep; src/a/b.rs is two deep
        let depth = parts.len() - usize::from(last == Some("mod.rs"));
        let escape = "super::".repeat(depth);
        let text = std::fs::read_to_string(file).expect("a source file is text");
        let lines = code_lines(&text);
        // the code as one text, so that a `crate::{…}` over several lines is read whole
        let mut code = String::new();
        let mut starts = Vec::new();
        for (number, line) in &lines {
            starts.push((code.len(), *number));
            code.push_str(line);
            code.push('\n');
            if line.contains(&escape) {
                escapes.push(format!("src/{}:{number}", relative.display()));
            }
        }
        let line_of = |offset: usize| {
            let i = starts.partition_point(|(start, _)| *start <= offset);
            starts[i.saturating_sub(1)].1
        };
        for (at, _) in code.match_indices("crate::") {
            // not the end of a longer name
            let before = code[..at].chars().next_back();
            if before.is_some_and(|c| c.is_ascii_alphanumeric() || c == '_') {
                continue;
            }
            let place = format!("src/{}:{}", relative.display(), line_of(at));
            for used in modules_after(&code[at + "crate::".len()..], modules) {
                if used != top {
                    uses.entry(top.clone())
                        .or_default()
                        .entry(used)
                        .or_insert_with(|| place.clone());
                }
            }
        }
    }
    (uses, escapes)
}

/// The floor a module's imports put it on: one above the highest module it uses, 0 when
/// it uses none; `Err` names a circle between modules.
fn lowest_floor(
    module: &str,
    uses: &Uses,
    floors: &mut BTreeMap<String, usize>,
    visiting: &mut Vec<String>,
) -> Result<usize, String> {
    if let Some(&floor) = floors.get(module) {
        return Ok(floor);
    }
    if let Some(at) = visiting.iter().position(|m| m == module) {
        let circle: Vec<String> = visiting[at..].iter().map(|m| format!("`{m}`")).collect();
        return Err(format!(
            "a circle between modules: {} → `{module}`",
            circle.join(" → ")
        ));
    }
    visiting.push(module.to_string());
    let mut floor = 0;
    for used in uses.get(module).into_iter().flat_map(BTreeMap::keys) {
        floor = floor.max(lowest_floor(used, uses, floors, visiting)? + 1);
    }
    visiting.pop();
    floors.insert(module.to_string(), floor);
    Ok(floor)
}

#[test]
fn the_floors_of_the_map_are_those_the_imports_give() {
    let modules = modules();
    assert!(
        modules.len() >= 10,
        "src/lib.rs declares the modules: {modules:?}"
    );
    let (uses, escapes) = imports(&modules);
    assert!(
        escapes.is_empty(),
        "these leave their top-level module through `super::`; write `crate::…`, so that \
         the floors are checked:\n{}",
        escapes.join("\n")
    );
    assert!(
        uses.values().map(BTreeMap::len).sum::<usize>() > 20,
        "the imports were found: {uses:?}"
    );
    let map = map_floors(&read(DOCUMENT), &modules);
    let mut floors = BTreeMap::new();
    let mut wrong = Vec::new();
    for module in &modules {
        let floor = lowest_floor(module, &uses, &mut floors, &mut Vec::new())
            .unwrap_or_else(|circle| panic!("{circle}"));
        let used: Vec<String> = uses
            .get(module)
            .into_iter()
            .flatten()
            .map(|(used, place)| format!("`{used}` (floor {}, {place})", floors[used]))
            .collect();
        let used = if used.is_empty() {
            "it uses no other module".to_string()
        } else {
            format!("it uses {}", used.join(", "))
        };
        match map.get(module).map(Vec::as_slice) {
            Some([on]) if *on == floor => {}
            Some([on]) => wrong.push(format!(
                "`{module}` is on floor {on} of the map, its imports put it on floor {floor}: \
                 {used}"
            )),
            Some(several) => wrong.push(format!("`{module}` is on floors {several:?} of the map")),
            None => wrong.push(format!(
                "`{module}` is on no floor of the map, its imports put it on floor {floor}: {used}"
            )),
        }
    }
    assert!(
        wrong.is_empty(),
        "the map of {DOCUMENT} (section \"The map\") is not the code's:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn imports_are_read_as_written() {
    let modules: Vec<String> = ["solve", "input", "kc"].map(String::from).to_vec();
    assert_eq!(modules_after("solve::Solution;", &modules), ["solve"]);
    assert_eq!(
        modules_after(
            "{input::{Location, text}, kc,\n    SOFTWARE_VERSION};",
            &modules
        ),
        ["input", "kc"]
    );
    assert_eq!(
        modules_after("SOFTWARE_VERSION", &modules),
        Vec::<String>::new()
    );
    let text = "//! crate::kc\nuse crate::solve; // crate::input\n#[cfg(test)]\nmod tests {\n    \
                use crate::kc;\n}\nfn f() {}\n#[cfg(all(test, unix))]\nmod more {\n}\n";
    assert_eq!(
        code_lines(text),
        [(2, "use crate::solve; "), (7, "fn f() {}")]
    );
}
