//! The one rule for every text cell exoleg writes (`gait_check.csv`, `faults.csv`,
//! `fmea.csv`, `fmea.md`) and every name it prints: names come from outside (file names, a
//! `subjects.csv`, a fault matrix's labels), so a cell never starts a spreadsheet formula
//! (`=`, `+`, `-`, `@`: a `'` goes before it, as OWASP advises for CSV injection), never holds
//! a control character (a newline that breaks a table, an ANSI escape that rewrites a
//! terminal: escaped as `\n`, `\u{1b}`), and in Markdown never splits a column (`\|`). A cell
//! that reads as a number is a number and stays as it is.

/// `s` with every control character escaped (one line, nothing that moves a terminal's cursor):
/// what exoleg prints of a name or a message.
pub fn terminal(s: &str) -> String {
    crate::control::plugin::escape_controls(s)
}

/// A scenario's name in a figure's title or a report's heading: its file name (and " (with
/// --set)"), never the absolute path the command resolved (a user's folders would be in every
/// figure they share); the embedded scenario's `<...>` name as it is.
pub fn title_name(source: &str) -> String {
    const WITH_SET: &str = " (with --set)";
    let (path, tail) = source.strip_suffix(WITH_SET).map_or((source, ""), |p| (p, WITH_SET));
    let name = match std::path::Path::new(path).file_name().and_then(|n| n.to_str()) {
        Some(n) if !path.starts_with('<') => n,
        _ => path,
    };
    terminal(&format!("{name}{tail}"))
}

/// A text cell: controls escaped, a leading formula character neutralised; a number as it is.
pub fn cell(s: &str) -> String {
    if s.trim().parse::<f64>().is_ok_and(f64::is_finite) && !s.chars().any(char::is_control) {
        return s.to_string();
    }
    let t = terminal(s);
    if t.starts_with(['=', '+', '-', '@']) {
        format!("'{t}")
    } else {
        t
    }
}

/// A CSV field: [`cell`], quoted when it holds a comma, a quote or a space at its ends.
pub fn csv_field(s: &str) -> String {
    let c = cell(s);
    if c.contains([',', '"']) || c.starts_with(' ') || c.ends_with(' ') {
        format!("\"{}\"", c.replace('"', "\"\""))
    } else {
        c
    }
}

/// A Markdown table cell: [`cell`] with `|` escaped.
pub fn markdown(s: &str) -> String {
    cell(s).replace('|', "\\|")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_never_start_a_formula_hold_a_control_or_split_a_column() {
        assert_eq!(cell("=HYPERLINK(1)"), "'=HYPERLINK(1)");
        assert_eq!(cell("-2 % FS"), "'-2 % FS");
        assert_eq!(cell("@evil"), "'@evil");
        assert_eq!(cell("+x"), "'+x");
        assert_eq!(cell("-1.5"), "-1.5");
        assert_eq!(cell("two\nlines"), "two\\nlines");
        assert_eq!(cell("\u{1b}[31mred"), "\\u{1b}[31mred");
        assert_eq!(cell("\n=1"), "\\n=1");
        assert_eq!(csv_field("a,b"), "\"a,b\"");
        assert_eq!(csv_field("say \"hi\""), "\"say \"\"hi\"\"\"");
        assert_eq!(markdown("a|b"), "a\\|b");
        assert_eq!(terminal("\u{1b}[2J"), "\\u{1b}[2J");
        assert_eq!(title_name("/home/me/secret/x.toml (with --set)"), "x.toml (with --set)");
        assert_eq!(title_name("<embedded default scenario>"), "<embedded default scenario>");
        assert_eq!(title_name("rel/y.toml"), "y.toml");
    }
}
