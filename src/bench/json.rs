//! `icefem bench --json`: the markdown tables a benchmark prints, as JSON.
//!
//! Every benchmark reports through lines of text — preamble notes and markdown table rows —
//! so one conversion serves them all: each table becomes its column names and rows, a cell
//! that is a plain number becomes a JSON number, any other cell stays text (`0.0093 (1 BLAS
//! thread: …)`, `–`), and the lines outside tables are kept as notes.

use serde_json::{json, Value};

/// The tables and notes in `lines` (as `bench::run` emits them) as one JSON object:
/// `{"tables": [{"columns": [...], "rows": [[...], ...]}, ...], "notes": [...]}`.
pub fn tables_to_json(lines: &[String]) -> Value {
    let mut tables: Vec<Value> = Vec::new();
    let mut notes = Vec::new();
    let mut columns: Option<Vec<String>> = None;
    let mut rows: Vec<Vec<Value>> = Vec::new();
    let mut finish = |columns: &mut Option<Vec<String>>, rows: &mut Vec<Vec<Value>>| {
        if let Some(c) = columns.take() {
            tables.push(json!({ "columns": c, "rows": std::mem::take(rows) }));
        }
    };
    for line in lines.iter().flat_map(|l| l.lines()) {
        let Some(cells) = table_cells(line) else {
            finish(&mut columns, &mut rows);
            if !line.trim().is_empty() {
                notes.push(line.trim().to_string());
            }
            continue;
        };
        if cells
            .iter()
            .all(|c| !c.is_empty() && c.chars().all(|ch| "-:".contains(ch)))
        {
            continue; // the separator row under the header
        }
        match &columns {
            None => columns = Some(cells),
            Some(_) => rows.push(cells.iter().map(|c| cell_value(c)).collect()),
        }
    }
    finish(&mut columns, &mut rows);
    json!({ "tables": tables, "notes": notes })
}

/// The cells of a markdown table row `| a | b |`, trimmed; `None` for other lines.
fn table_cells(line: &str) -> Option<Vec<String>> {
    let inner = line.trim().strip_prefix('|')?.strip_suffix('|')?;
    Some(inner.split('|').map(|c| c.trim().to_string()).collect())
}

/// A number where the cell is one, else the text.
fn cell_value(cell: &str) -> Value {
    match cell.parse::<f64>() {
        Ok(v) if v.is_finite() => json!(v),
        _ => json!(cell),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_become_columns_and_rows_and_the_rest_notes() {
        let lines: Vec<String> = [
            "Times in seconds.\n",
            "| tets | step (s) | note |",
            "|---|---:|---|",
            "| 1296 | 0.00321 | – |",
            "| 10368 | 4.4e-2 | 3 / 3 |",
            "scaling: 1.1",
        ]
        .map(String::from)
        .to_vec();
        let v = tables_to_json(&lines);
        assert_eq!(
            v["tables"][0]["columns"],
            json!(["tets", "step (s)", "note"])
        );
        assert_eq!(v["tables"][0]["rows"][0], json!([1296.0, 0.00321, "–"]));
        assert_eq!(v["tables"][0]["rows"][1], json!([10368.0, 0.044, "3 / 3"]));
        assert_eq!(v["notes"], json!(["Times in seconds.", "scaling: 1.1"]));
    }
}
