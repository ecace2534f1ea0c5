//! The README's and the guides' shell blocks, run as written (issue 8: "every command the
//! README shows must run as written"), and every output they show compared with what the
//! command beside it prints (issue 36: "every table in the README comes from a command
//! shown beside it, run in CI").
//!
//! - Every ```sh block of `README.md` and of each guide in `docs/` is run, in order, each
//!   document in a copy of the repository's tracked files (`git ls-files`, as they are in
//!   the working tree) made a git repository of its own, from its root as the README
//!   says, with `cargo run --release --` and `target/release/polycal` standing for the
//!   built binary. After each document `git status --porcelain` must be empty (issue 48:
//!   following the README left about 25 untracked files in the repository's root): what
//!   the commands write goes under `out/`, which git ignores. The copy is then cleaned,
//!   so that each guide's commands run as a reader who starts there runs them. The
//!   documents run at once in a few copies, each copy's one after another.
//!   `cargo build`/`cargo test` lines are left out (this test is run by them), and so
//!   are blocks preceded by a `<!-- tests/sweeps/readme.rs skips … -->` line (the
//!   two-terminal instructions, whose device paths differ on every machine; the same run
//!   is shown as one script, which is run).
//! - A ```sh block followed by a `<!-- output of the block above -->` line and then a
//!   ```text block shows its output: the block's standard output must be that text (line
//!   by line, trailing spaces aside), so that a figure that drifts fails here.
//! - Every relative link of these documents (`[…](path)`, `[…](path#anchor)`,
//!   `[…](#anchor)`) names a file that exists and, with an anchor, a heading of it.

#![cfg(unix)]

use std::path::{Path, PathBuf};
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_polycal");
const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// The marker between a ```sh block and the ```text block of its output.
const OUTPUT_MARKER: &str = "<!-- output of the block above -->";

/// A ```sh block to run: where it starts, its lines, and the output it shows, if any
/// (the line of that ```text block and its text).
#[derive(Debug)]
struct Block {
    line: usize,
    body: Vec<String>,
    output: Option<(usize, String)>,
}

/// The ```sh blocks of a document that are to be run, each with the output it shows.
fn runnable_blocks(document: &str) -> Vec<Block> {
    let lines: Vec<&str> = document.lines().collect();
    let mut blocks = Vec::new();
    let mut skip_next = false;
    let mut i = 0;
    while i < lines.len() {
        let line = lines[i];
        i += 1;
        if line.starts_with("<!-- tests/sweeps/readme.rs skips") {
            skip_next = true;
            continue;
        }
        if line.trim_end() != "```sh" {
            continue;
        }
        let start = i;
        let mut body = Vec::new();
        while i < lines.len() && !lines[i].starts_with("```") {
            body.push(lines[i].to_string());
            i += 1;
        }
        i += 1; // the closing fence
        // the output shown beside it: the marker, then a ```text block
        let mut j = i;
        while j < lines.len() && lines[j].trim().is_empty() {
            j += 1;
        }
        let mut output = None;
        if j < lines.len() && lines[j].trim_end() == OUTPUT_MARKER {
            j += 1;
            while j < lines.len() && lines[j].trim().is_empty() {
                j += 1;
            }
            assert!(
                j < lines.len() && lines[j].trim_end() == "```text",
                "line {}: {OUTPUT_MARKER} is followed by a ```text block",
                j + 1
            );
            let text_line = j + 1;
            j += 1;
            let mut text = Vec::new();
            while j < lines.len() && !lines[j].starts_with("```") {
                text.push(lines[j]);
                j += 1;
            }
            output = Some((text_line, text.join("\n")));
            i = j + 1;
        }
        if std::mem::take(&mut skip_next) {
            continue;
        }
        blocks.push(Block {
            line: start,
            body,
            output,
        });
    }
    blocks
}

/// A block as a bash script for the built binary.
fn script(body: &[String]) -> String {
    let mut out = String::from("set -euo pipefail\n");
    for line in body {
        let trimmed = line.trim_start();
        if trimmed.starts_with("cargo ") && !trimmed.starts_with("cargo run --release --") {
            continue; // building and testing: what runs this test
        }
        out.push_str(
            &line
                .replace("cargo run --release --", "\"$POLYCAL\"")
                .replace("target/release/polycal", "\"$POLYCAL\""),
        );
        out.push('\n');
    }
    out
}

/// Text compared line by line, trailing spaces and trailing blank lines aside.
fn normalized(text: &str) -> Vec<String> {
    let mut lines: Vec<String> = text.lines().map(|l| l.trim_end().to_string()).collect();
    while lines.last().is_some_and(|l| l.is_empty()) {
        lines.pop();
    }
    lines
}

/// README.md and the guides in docs/, each a path relative to the repository.
fn documents() -> Vec<PathBuf> {
    let mut guides: Vec<PathBuf> = std::fs::read_dir(Path::new(ROOT).join("docs"))
        .expect("docs/")
        .map(|e| e.expect("a docs/ entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .map(|p| Path::new("docs").join(p.file_name().expect("a file name")))
        .collect();
    guides.sort();
    let mut all = vec![PathBuf::from("README.md")];
    all.extend(guides);
    all
}

/// Runs `git ARGS` in `dir`; its standard output, or a panic naming the command.
fn git(dir: &Path, args: &[&str]) -> String {
    let output = Command::new("git")
        .args([
            "-c",
            "user.name=polycal tests",
            "-c",
            "user.email=tests@polycal.invalid",
        ])
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap_or_else(|e| panic!("git {args:?} cannot run: {e}"));
    assert!(
        output.status.success(),
        "git {args:?} in {} failed: {}",
        dir.display(),
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout).into_owned()
}

/// A copy of the repository's tracked files as they are in the working tree (a fresh
/// clone, with the changes not yet committed), committed as a repository of its own in
/// a new directory named after `name`.
fn repository_copy(name: &str) -> PathBuf {
    let copy = std::env::temp_dir().join(format!("polycal-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&copy);
    std::fs::create_dir_all(&copy).expect("a scratch directory");
    for path in git(Path::new(ROOT), &["ls-files", "-z"]).split('\0') {
        let from = Path::new(ROOT).join(path);
        if path.is_empty() || !from.is_file() {
            continue; // the end, or a tracked file deleted in the working tree
        }
        let to = copy.join(path);
        std::fs::create_dir_all(to.parent().expect("a parent")).expect("a directory");
        std::fs::copy(&from, &to).unwrap_or_else(|e| panic!("{path}: {e}"));
    }
    git(&copy, &["init", "-q"]);
    git(&copy, &["add", "-A"]);
    git(
        &copy,
        &["commit", "-q", "--no-gpg-sign", "-m", "the tracked files"],
    );
    copy
}

/// What commands left in a repository copy: `git status --porcelain`, one line a path
/// (every untracked file named, not only its directory).
fn left_behind(copy: &Path) -> Vec<String> {
    git(copy, &["status", "--porcelain", "--untracked-files=all"])
        .lines()
        .map(str::to_string)
        .collect()
}

/// Runs a document's blocks from the root of the repository copy `copy`; a failure names
/// the document and line. Afterwards nothing may be left but under `out/` (ignored), and
/// the copy is cleaned for the next document.
fn run_document(document: &Path, copy: &Path) -> usize {
    let text = std::fs::read_to_string(Path::new(ROOT).join(document))
        .unwrap_or_else(|e| panic!("{}: {e}", document.display()));
    let blocks = runnable_blocks(&text);
    if blocks.is_empty() {
        return 0;
    }
    run_blocks(document, &blocks, copy);
    let left = left_behind(copy);
    assert!(
        left.is_empty(),
        "{}: its commands left files outside out/ (git status --porcelain):\n{}",
        document.display(),
        left.join("\n")
    );
    git(copy, &["clean", "-q", "-f", "-d", "-x"]);
    blocks.len()
}

/// Runs blocks, in order, from `dir`; a failure names the document and line.
fn run_blocks(document: &Path, blocks: &[Block], dir: &Path) {
    for block in blocks {
        let text = script(&block.body);
        let output = Command::new("bash")
            .arg("-c")
            .arg(&text)
            .current_dir(dir)
            .env("POLYCAL", BIN)
            .env_remove("NO_COLOR")
            .output()
            .expect("bash runs");
        let stdout = String::from_utf8_lossy(&output.stdout);
        assert!(
            output.status.success(),
            "{} block at line {} failed ({}):\n{text}\nstdout:\n{stdout}\nstderr:\n{}",
            document.display(),
            block.line,
            output.status,
            String::from_utf8_lossy(&output.stderr)
        );
        if let Some((line, shown)) = &block.output {
            let (shown, printed) = (normalized(shown), normalized(&stdout));
            assert!(
                shown == printed,
                "{}: the output shown at line {line} is not what the block at line {} prints \
                 (first difference at its line {}):\nshown:\n{}\nprinted:\n{}",
                document.display(),
                block.line,
                shown
                    .iter()
                    .zip(&printed)
                    .position(|(a, b)| a != b)
                    .unwrap_or(shown.len().min(printed.len()))
                    + 1,
                shown.join("\n"),
                printed.join("\n")
            );
        }
    }
}

/// How many copies of the repository the documents' blocks run in at once.
const WORKERS: usize = 3;

#[test]
fn the_shell_blocks_run_as_written_and_print_what_is_shown() {
    let mut shown = 0;
    // those with a block to run, the ones that start a simulated lab first: their blocks
    // wait on it (docs/instruments.md most of this test's time) rather than compute
    let mut documents = Vec::new();
    for document in self::documents() {
        let text = std::fs::read_to_string(Path::new(ROOT).join(&document)).expect("readable");
        let blocks = runnable_blocks(&text);
        shown += blocks.iter().filter(|b| b.output.is_some()).count();
        let lab = blocks
            .iter()
            .any(|b| b.body.iter().any(|l| l.contains("sim-lab")));
        if !blocks.is_empty() {
            documents.push((!lab, document));
        }
    }
    documents.sort_by_key(|(computes, _)| *computes); // stable: otherwise in order
    // The documents at once, on a few workers, each with a repository copy of its own in
    // which it runs one document after another (their blocks in order), the copy cleaned
    // between them (run_document): each as a reader who starts there runs them. A
    // failure's message names its document; the first worker's in order is the test's.
    let next = std::sync::atomic::AtomicUsize::new(0);
    let workers: Vec<std::thread::Result<usize>> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..WORKERS.min(documents.len()))
            .map(|worker| {
                let (documents, next) = (&documents, &next);
                scope.spawn(move || {
                    let copy = repository_copy(&format!("readme-{worker}"));
                    let mut count = 0;
                    while let Some((_, document)) =
                        documents.get(next.fetch_add(1, std::sync::atomic::Ordering::Relaxed))
                    {
                        count += run_document(document, &copy);
                    }
                    let _ = std::fs::remove_dir_all(&copy);
                    count
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join()).collect()
    });
    let mut total = 0;
    for worker in workers {
        match worker {
            Ok(count) => total += count,
            Err(failure) => std::panic::resume_unwind(failure),
        }
    }
    assert!(
        total >= 5,
        "expected the set-up, diagnose, uncertainty, command and lab blocks, found {total}"
    );
    assert!(
        shown >= 2,
        "expected the plan comparison and the solve table beside their commands, found {shown}"
    );
}

/// The check of what commands leave: a file written in the root is named, one under
/// `out/` is not, and a changed tracked file is named too.
#[test]
fn what_commands_leave_outside_out_is_found() {
    let copy = repository_copy("readme-check");
    assert_eq!(
        left_behind(&copy),
        Vec::<String>::new(),
        "a fresh copy is clean"
    );
    let document = "```sh\nmkdir -p figures\necho x > out/result.csv\necho x > result.csv\n\
                    echo x > figures/a.svg\necho x >> Cargo.toml\n```\n";
    run_blocks(Path::new("test"), &runnable_blocks(document), &copy);
    assert_eq!(
        left_behind(&copy),
        vec![" M Cargo.toml", "?? figures/a.svg", "?? result.csv"]
    );
    let _ = std::fs::remove_dir_all(&copy);
}

#[test]
fn the_skip_marker_and_the_cargo_lines_are_honoured() {
    let readme = "<!-- tests/sweeps/readme.rs skips this -->\n```sh\nfalse\n```\n\n```sh\ncargo test\ncargo run --release -- solve x.csv\n```\n";
    let blocks = runnable_blocks(readme);
    assert_eq!(blocks.len(), 1);
    assert_eq!(
        script(&blocks[0].body),
        "set -euo pipefail\n\"$POLYCAL\" solve x.csv\n"
    );
}

#[test]
fn an_output_block_is_paired_with_the_block_above_and_compared() {
    let document = format!(
        "```sh\necho a\n```\n\n{OUTPUT_MARKER}\n\n```text\na\n```\n\n```sh\necho b\n```\n\n```text\nnot an output\n```\n"
    );
    let blocks = runnable_blocks(&document);
    assert_eq!(blocks.len(), 2);
    assert_eq!(blocks[0].output, Some((7, "a".to_string())));
    assert_eq!(blocks[1].output, None);
    // the comparison: trailing spaces and blank lines aside, nothing else
    assert_eq!(normalized("x  \ny\n\n"), normalized("x\ny"));
    assert_ne!(normalized("0.0282"), normalized("0.0283"));
}

/// GitHub's anchor of a heading: lower case, punctuation but `-` and `_` dropped, spaces
/// as `-`.
fn anchor_of(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || matches!(c, ' ' | '-' | '_'))
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// The anchors of a document's headings (outside code blocks).
fn anchors(document: &str) -> Vec<String> {
    let mut in_code = false;
    let mut out = Vec::new();
    for line in document.lines() {
        if line.starts_with("```") {
            in_code = !in_code;
            continue;
        }
        if !in_code && line.starts_with('#') {
            out.push(anchor_of(line.trim_start_matches('#')));
        }
    }
    out
}

/// The relative link targets of a document (outside code blocks and code spans): what
/// stands in `](…)`, without web addresses.
fn links(document: &str) -> Vec<(usize, String)> {
    let mut in_code = false;
    let mut out = Vec::new();
    for (number, line) in document.lines().enumerate() {
        if line.starts_with("```") {
            in_code = !in_code;
            continue;
        }
        if in_code {
            continue;
        }
        // code spans hold no links
        let text: String = line
            .split('`')
            .enumerate()
            .filter(|(i, _)| i % 2 == 0)
            .map(|(_, part)| part)
            .collect::<Vec<_>>()
            .join(" ");
        let mut rest = text.as_str();
        while let Some(at) = rest.find("](") {
            let after = &rest[at + 2..];
            let Some(end) = after.find(')') else { break };
            let target = after[..end].trim();
            if !target.contains("://") && !target.starts_with("mailto:") {
                out.push((number + 1, target.to_string()));
            }
            rest = &after[end..];
        }
    }
    out
}

#[test]
fn every_link_between_the_readme_and_the_guides_resolves() {
    let mut checked = 0;
    for document in documents() {
        let text = std::fs::read_to_string(Path::new(ROOT).join(&document)).expect("readable");
        let dir = document.parent().unwrap_or(Path::new(""));
        for (line, target) in links(&text) {
            let (path, anchor) = match target.split_once('#') {
                Some((p, a)) => (p, Some(a)),
                None => (target.as_str(), None),
            };
            let file = if path.is_empty() {
                document.clone()
            } else {
                dir.join(path)
            };
            let full = Path::new(ROOT).join(&file);
            assert!(
                full.exists(),
                "{}:{line}: the link {target:?} names {}, which does not exist",
                document.display(),
                file.display()
            );
            if let Some(anchor) = anchor {
                let linked = std::fs::read_to_string(&full).unwrap_or_else(|e| {
                    panic!("{}:{line}: {}: {e}", document.display(), file.display())
                });
                assert!(
                    anchors(&linked).iter().any(|a| a == anchor),
                    "{}:{line}: the link {target:?}: {} has no heading #{anchor}",
                    document.display(),
                    file.display()
                );
            }
            checked += 1;
        }
    }
    assert!(checked > 0, "the README links to its guides");
}

#[test]
fn anchors_and_links_are_read_as_github_reads_them() {
    assert_eq!(
        anchor_of(" Closing the loop: `polycal diagnose`"),
        "closing-the-loop-polycal-diagnose"
    );
    assert_eq!(
        anchor_of("The paper's Table 1 with `polycal budget`"),
        "the-papers-table-1-with-polycal-budget"
    );
    let text =
        "see [a](docs/a.md#x) and `[b](no.md)` and [c](https://e.org)\n```\n[d](no.md)\n```\n";
    assert_eq!(links(text), vec![(1, "docs/a.md#x".to_string())]);
}

/// The flags `polycal COMMAND --help` lists (every `--name` at the start of a line of
/// its Options section).
fn help_flags(command: &str) -> Vec<String> {
    let output = Command::new(BIN)
        .args([command, "--help"])
        .output()
        .expect("polycal runs");
    assert!(output.status.success(), "polycal {command} --help");
    let help = String::from_utf8_lossy(&output.stdout);
    // the options, not the examples after them
    let options = help
        .split("\nOptions:")
        .nth(1)
        .expect("an Options: section");
    let options = options.split("\nExamples:").next().unwrap_or(options);
    let mut flags: Vec<String> = options
        .lines()
        .map(str::trim_start)
        .filter(|l| l.starts_with('-'))
        .flat_map(|l| l.split([' ', ',', '=', '[', '<']).take(3))
        .filter(|w| w.starts_with("--") && w.len() > 2)
        .map(str::to_string)
        .collect();
    flags.sort();
    flags.dedup();
    flags
}

/// Issue 48: the README's command summary lacked `--covariance`, `--cross-talk`,
/// `--head-angle-u` and `--step-seconds`. Every flag of every evaluating command's
/// `--help` is in its entry of the summary (its `polycal COMMAND` lines and their
/// continuation lines), `--plot` in the note that names the commands taking it, and
/// `--help`, `--quiet` and `--color` in the paragraph that says every command takes them.
#[test]
fn the_command_summary_lists_every_flag_of_every_command() {
    let readme = std::fs::read_to_string(Path::new(ROOT).join("README.md")).expect("README");
    let section = &readme[readme.find("\n## Commands\n").expect("## Commands")..];
    let block_start = section.find("```text\n").expect("the summary block") + 8;
    let block = &section[block_start..block_start + section[block_start..].find("```").unwrap()];
    let paragraph = section[block_start + block.len() + 3..].trim_start();
    let paragraph = &paragraph[..paragraph.find("\n\n").expect("a paragraph")];
    let plot_note = block
        .lines()
        .find(|l| l.trim_start().starts_with('(') && l.contains("--plot"))
        .expect("the --plot note");
    for command in [
        "solve", "diagnose", "budget", "compare", "kc", "simulate", "selfcal", "plan", "report",
    ] {
        // the command's entries: its lines and their indented continuations
        let mut entry = String::new();
        let mut inside = false;
        for line in block.lines() {
            if line.starts_with("polycal ") {
                inside = line.starts_with(&format!("polycal {command} "));
            } else if line.trim_start().starts_with('(') {
                inside = false;
            }
            if inside {
                entry.push_str(line);
                entry.push('\n');
            }
        }
        assert!(!entry.is_empty(), "no entry for polycal {command}");
        let flags = help_flags(command);
        assert!(flags.len() >= 3, "polycal {command} --help: {flags:?}");
        for flag in flags {
            let listed = match flag.as_str() {
                "--help" | "--quiet" | "--color" => paragraph.contains(flag.as_str()),
                "--plot" => plot_note.contains(command),
                _ => entry
                    .split(|c: char| !(c.is_alphanumeric() || c == '-'))
                    .any(|w| w == flag),
            };
            assert!(
                listed,
                "README's command summary: polycal {command} {flag} is not listed"
            );
        }
    }
}
