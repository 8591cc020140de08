//! The documentation a user of the repository reads: `docs/scene-format.md` lists exactly
//! the fields the parser accepts, the README and docs link only to files in the
//! repository, and every command's `--help` explains every option.

use std::collections::BTreeMap;
use std::path::Path;

use crate::common::cli::{nimbus, text};

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The field tables of the scene-format page: `### <table>` headings under "## Tables",
/// each with the fields named in the first column of its rows (`| `field` | ...`).
fn documented_tables(page: &str) -> BTreeMap<String, Vec<String>> {
    let mut tables = BTreeMap::new();
    let mut current: Option<String> = None;
    let mut in_tables = false;
    for line in page.lines() {
        if let Some(h) = line.strip_prefix("## ") {
            in_tables = h.trim() == "Tables";
            current = None;
        } else if let Some(h) = line.strip_prefix("### ").filter(|_| in_tables) {
            current = Some(h.trim().to_string());
            tables.insert(h.trim().to_string(), Vec::new());
        } else if let (Some(table), Some(row)) = (&current, line.strip_prefix("| `")) {
            let field = row.split('`').next().unwrap_or("").to_string();
            tables.get_mut(table).unwrap().push(field);
        }
    }
    tables
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
                "docs/", "tools/", "assets/", "src/", "shaders/", "tests/", ".ci/",
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
    let study = text(&nimbus(&["study", "--help"]).stdout);
    for key in nimbus::study::vary_keys() {
        assert!(
            study.contains(key),
            "study --help does not list the --vary key {key}"
        );
    }
}
