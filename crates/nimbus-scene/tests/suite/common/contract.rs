//! The field tables of the scene contract, `docs/scene-format.md`, as the tests read them.
//! Shared by this crate's hostile suite and the renderer's docs test (which includes this
//! file by path), so both read the contract one way.

use std::collections::BTreeMap;

/// The `### <table>` headings under "## Tables" of the scene-format page, each with the
/// fields named in the first column of its rows (`| `field` | ...`).
pub fn documented_tables(page: &str) -> BTreeMap<String, Vec<String>> {
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
