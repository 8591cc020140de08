//! The documentation a user of the repository reads: `docs/scene-format.md` lists exactly
//! the fields the parser accepts, the README and docs link only to files in the
//! repository, and every command's `--help` explains every option.

use std::path::Path;

use crate::common::cli::{nimbus, text};

// The scene crate's reading of the contract's field tables (one parser for both suites).
#[path = "../../../crates/nimbus-scene/tests/suite/common/contract.rs"]
mod contract;
use contract::documented_tables;

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn the_scene_format_page_lists_exactly_the_fields_the_parser_accepts() {
    let page = std::fs::read_to_string(repo().join("docs/scene-format.md")).unwrap();
    let documented = documented_tables(&page);
    let parser = nimbus_scene::scene_tables();
    let mut problems = Vec::new();
    for t in &parser {
        match documented.get(&t.table) {
            None => problems.push(format!("no section `### {}`", t.table)),
            Some(fields) => {
                for f in &t.fields {
                    if !fields.iter().any(|d| d == f) {
                        problems.push(format!("{}: field `{f}` is not documented", t.table));
                    }
                }
                for d in fields {
                    if !t.fields.contains(&d.as_str()) {
                        problems.push(format!(
                            "{}: documents `{d}`, which the parser refuses",
                            t.table
                        ));
                    }
                }
            }
        }
    }
    for table in documented.keys() {
        if !parser.iter().any(|t| &t.table == table) {
            problems.push(format!("section `### {table}` is no table of the parser"));
        }
    }
    assert!(
        problems.is_empty(),
        "docs/scene-format.md vs the parser:\n{}",
        problems.join("\n")
    );
}

/// Relative link targets `](path)` and backticked repository paths in `text`.
fn referenced_paths(text: &str) -> Vec<String> {
    let mut paths = Vec::new();
    for part in text.split("](").skip(1) {
        let target = part.split(')').next().unwrap_or("");
        if !target.contains("://") && !target.starts_with('#') {
            paths.push(target.split('#').next().unwrap_or("").to_string());
        }
    }
    for (i, part) in text.split('`').enumerate() {
        let is_path = i % 2 == 1
            && !part.contains(' ')
            && [
                "docs/", "tools/", "assets/", "src/", "shaders/", "tests/", ".ci/", "crates/",
            ]
            .iter()
            .any(|p| part.starts_with(p));
        if is_path && !part.contains('*') && !part.contains('{') && !part.contains('<') {
            paths.push(part.trim_end_matches([',', '.', ':']).to_string());
        }
    }
    paths
}

#[test]
fn readme_and_docs_point_only_into_the_repository() {
    let mut problems = Vec::new();
    let mut pages = vec![repo().join("README.md"), repo().join("tools/README.md")];
    for entry in std::fs::read_dir(repo().join("docs")).unwrap().flatten() {
        if entry.path().extension().is_some_and(|e| e == "md") {
            pages.push(entry.path());
        }
    }
    for page in pages {
        let body = std::fs::read_to_string(&page).unwrap();
        let name = page.strip_prefix(repo()).unwrap().display().to_string();
        if body.contains("../shared") || body.contains("shared/SCENE_FORMAT") {
            problems.push(format!("{name} points outside the repository (../shared)"));
        }
        let base = if name.starts_with("docs/") && body.contains("](") {
            page.parent().unwrap().to_path_buf()
        } else {
            repo().to_path_buf()
        };
        for path in referenced_paths(&body) {
            // Links resolve against the page; backticked paths name repository paths.
            let exists = repo().join(&path).exists() || base.join(&path).exists();
            if !path.is_empty() && !exists {
                problems.push(format!("{name} names `{path}`, which does not exist"));
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn every_option_of_every_command_has_help() {
    for command in ["render", "merge", "profile", "study", "devices"] {
        let out = nimbus(&[command, "-h"]);
        let help = text(&out.stdout);
        assert!(out.status.success(), "{command} -h: {}", text(&out.stderr));
        assert!(
            !help.contains("shared/"),
            "{command} -h points outside the repository"
        );
        let lines: Vec<&str> = help.lines().collect();
        for (i, line) in lines.iter().enumerate() {
            // Arguments sit 2 to 6 columns in; their texts deeper.
            let trimmed = line.trim_start();
            let indent = line.len() - trimmed.len();
            let argument =
                trimmed.starts_with('-') || trimmed.starts_with('[') || trimmed.starts_with('<');
            if !argument || !(2..=6).contains(&indent) {
                continue;
            }
            // "  --width <PIXELS>  Image width ...", or the text on the next, deeper line.
            let same_line = trimmed.split("  ").filter(|s| !s.trim().is_empty()).count() >= 2;
            let next_line = lines.get(i + 1).is_some_and(|next| {
                let t = next.trim_start();
                !t.is_empty() && next.len() - t.len() > indent && !t.starts_with('-')
            });
            assert!(
                same_line || next_line,
                "{command} -h: no help text for {trimmed:?}"
            );
        }
    }
    // `nimbus study --help` is nimbus-study's; its test checks the --vary keys.
}

/// Paths named in comments (`//`, `//!`, `///` in Rust; `//` in GLSL), backticked or
/// bare, with a known extension.
fn comment_paths(text: &str) -> Vec<String> {
    let mut paths = Vec::new();
    for line in text.lines() {
        let Some((_, comment)) = line.split_once("//") else {
            continue;
        };
        // Backticked paths as in the docs (not rustdoc's intra-doc links such as
        // `[x](super::Y)`), and bare ones ending in a source extension.
        paths.extend(
            referenced_paths(comment)
                .into_iter()
                .filter(|p| p.contains('/') && !p.contains("::")),
        );
        for word in comment.split(|c: char| c.is_whitespace() || "()`,;".contains(c)) {
            let word = word.trim_end_matches(['.', ':']);
            let known_dir = ["src/", "shaders/", "tests/", "docs/", "tools/", "assets/"]
                .iter()
                .any(|p| word.starts_with(p));
            let known_ext = [".rs", ".glsl", ".comp", ".md", ".toml", ".sh"]
                .iter()
                .any(|e| word.ends_with(e));
            if known_dir && known_ext && !word.contains(['*', '{', '<', 'N']) {
                paths.push(word.to_string());
            }
        }
    }
    paths
}

/// Shader files named in comments by their include path (`grid.glsl`,
/// `restir/combine.glsl`): words ending in `.glsl` or `.comp` that do not start with a
/// repository folder (those are [`comment_paths`]').
fn shader_names(text: &str) -> Vec<String> {
    let mut names = Vec::new();
    for line in text.lines() {
        let Some((_, comment)) = line.split_once("//") else {
            continue;
        };
        for word in comment.split(|c: char| c.is_whitespace() || "()`,;'\"[]".contains(c)) {
            let word = word.trim_end_matches(['.', ':']);
            let shader = word.ends_with(".glsl") || word.ends_with(".comp");
            let rooted = ["src/", "shaders/", "tests/", "docs/", "crates/", "$"]
                .iter()
                .any(|p| word.starts_with(p));
            let stem = word.rsplit('/').next().unwrap_or("");
            let named = !stem.starts_with('.') && stem != "x.glsl";
            if shader && named && !rooted && !word.contains(['*', '{', '}', '<', '$']) {
                names.push(word.to_string());
            }
        }
    }
    names
}

/// Every source file under `dir` with one of `exts`.
fn sources(dir: &Path, exts: &[&str], out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let path = entry.path();
        if path.is_dir() {
            sources(&path, exts, out);
        } else if path
            .extension()
            .is_some_and(|e| exts.iter().any(|x| e == *x))
        {
            out.push(path);
        }
    }
}

/// Issue 25: comments named files that had moved (the bindings module before it went
/// under src/shader_data, the layout test before the suite, the scene contract outside the
/// repository). Every path a comment names exists, from the repository's root or from
/// its crate's.
#[test]
fn comments_point_only_to_files_that_exist() {
    let mut files = Vec::new();
    for dir in ["src", "tests", "shaders", "crates", "examples", "build.rs"] {
        let path = repo().join(dir);
        if path.is_file() {
            files.push(path);
        } else {
            sources(&path, &["rs", "glsl", "comp"], &mut files);
        }
    }
    let mut shader_files = Vec::new();
    sources(
        &repo().join("shaders"),
        &["glsl", "comp"],
        &mut shader_files,
    );
    let mut problems = Vec::new();
    for file in files {
        let text = std::fs::read_to_string(&file).unwrap();
        let name = file.strip_prefix(repo()).unwrap().display().to_string();
        // The crate a file belongs to (crates/<name>/...), else the repository.
        let crate_root = name
            .strip_prefix("crates/")
            .and_then(|rest| rest.split('/').next())
            .map(|c| repo().join("crates").join(c));
        let outside = text.contains("shared/SCENE_FORMAT") || text.contains("shared/ARCHITECTURE");
        if outside && name != "tests/suite/commands/docs.rs" {
            problems.push(format!("{name} points outside the repository (shared/)"));
        }
        for path in comment_paths(&text) {
            let exists = repo().join(&path).exists()
                || crate_root.as_ref().is_some_and(|c| c.join(&path).exists());
            if !exists {
                problems.push(format!("{name} names `{path}`, which does not exist"));
            }
        }
        // Shader files named as includes name them (`restir/path_value.glsl`,
        // `grid.glsl`): from shaders/, shaders/include/ or the file's own folder, or a
        // header build.rs generates.
        // A bare name (`pathtrace.comp`) is any shader of that name.
        let own_dir = file.parent().unwrap().to_path_buf();
        for word in shader_names(&text) {
            let generated = word.starts_with("gpu_");
            let exists = if word.contains('/') {
                [
                    repo().join("shaders"),
                    repo().join("shaders/include"),
                    own_dir.clone(),
                ]
                .iter()
                .any(|d| d.join(&word).exists())
            } else {
                shader_files
                    .iter()
                    .any(|f| f.file_name() == Some(word.as_ref()))
            };
            if !generated && !exists {
                problems.push(format!(
                    "{name} names shader `{word}`, which does not exist"
                ));
            }
        }
    }
    problems.sort();
    problems.dedup();
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The README's install command ends in `cargo run -- render`: at the workspace root that
/// builds every default member, and with nimbus-study's binary among them `cargo run`
/// cannot tell which binary is meant unless the root package names its own (it failed
/// so when the study moved into its own crate).
#[test]
fn cargo_run_at_the_root_runs_the_renderer() {
    let manifest = std::fs::read_to_string(repo().join("Cargo.toml")).unwrap();
    let readme = std::fs::read_to_string(repo().join("README.md")).unwrap();
    assert!(
        readme.contains("cargo run -- render"),
        "the README's command changed"
    );
    let members = manifest
        .lines()
        .find(|l| l.starts_with("default-members"))
        .expect("default-members");
    if members.contains("crates/nimbus-study") {
        assert!(
            manifest.contains("default-run = \"nimbus\""),
            "Cargo.toml: [package] needs default-run = \"nimbus\" for the README's `cargo run`"
        );
    }
}
