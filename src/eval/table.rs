//! The one table type of the evaluation suites: a header and rows of formatted cells,
//! rendered as a markdown table (what `glocal eval` prints and docs/RESULTS.md holds) and as
//! JSON (the same cells, beside the suite's raw numbers).

use serde_json::{json, Value};

#[derive(Clone, Debug, PartialEq)]
pub struct Table {
    columns: Vec<String>,
    rows: Vec<Vec<String>>,
}

impl Table {
    pub fn new<S: Into<String>>(columns: impl IntoIterator<Item = S>) -> Self {
        Self { columns: columns.into_iter().map(Into::into).collect(), rows: Vec::new() }
    }

    /// Appends a row; missing cells at the end are left empty.
    pub fn row<S: Into<String>>(&mut self, cells: impl IntoIterator<Item = S>) {
        let mut cells: Vec<String> = cells.into_iter().map(Into::into).collect();
        debug_assert!(cells.len() <= self.columns.len(), "a row wider than the header");
        cells.resize(self.columns.len(), String::new());
        self.rows.push(cells);
    }

    pub fn markdown(&self) -> String {
        let mut out = markdown_line(&self.columns);
        out.push('|');
        out.push_str(&"---|".repeat(self.columns.len()));
        out.push('\n');
        for row in &self.rows {
            out.push_str(&markdown_line(row));
        }
        out
    }

    pub fn json(&self) -> Value {
        json!({"columns": self.columns, "rows": self.rows})
    }
}

/// `| a | b |`, an empty cell as `| |`.
fn markdown_line(cells: &[String]) -> String {
    let mut line = String::from("|");
    for c in cells {
        if c.is_empty() {
            line.push_str(" |");
        } else {
            line.push_str(&format!(" {c} |"));
        }
    }
    line.push('\n');
    line
}

/// A suite's printed text: prose and tables in order, the tables also kept for the JSON.
#[derive(Default)]
pub struct Markdown {
    text: String,
    tables: Vec<Table>,
}

impl Markdown {
    pub fn new(text: impl Into<String>) -> Self {
        Self { text: text.into(), tables: Vec::new() }
    }

    pub fn text(&mut self, s: &str) {
        self.text.push_str(s);
    }

    pub fn table(&mut self, t: Table) {
        self.text.push_str(&t.markdown());
        self.tables.push(t);
    }

    pub fn into_parts(self) -> (String, Vec<Table>) {
        (self.text, self.tables)
    }
}

/// `v` with `digits` decimals, "n/a" when it is not finite.
pub fn fixed(v: f64, digits: usize) -> String {
    fixed_or(v, digits, "n/a")
}

/// `v` with `digits` decimals, `missing` when it is not finite.
pub fn fixed_or(v: f64, digits: usize, missing: &str) -> String {
    if v.is_finite() {
        format!("{v:.digits$}")
    } else {
        missing.into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markdown_writes_empty_cells_as_a_single_space() {
        let mut t = Table::new(["method", "a", "b"]);
        t.row(["x", "1.0", "2.0"]);
        t.row(["*paper*", "0.5"]);
        assert_eq!(t.markdown(), "| method | a | b |\n|---|---|---|\n| x | 1.0 | 2.0 |\n| *paper* | 0.5 | |\n");
        assert_eq!(t.json()["rows"][1][2], "");
    }
}
