//! `subjects.csv`: the table of a folder of gait trials (`exoleg gait-check`). One row per trial
//! file, with the numbers of the subject who walked it; each trial runs from its row alone.
//!
//! | column | unit | required | meaning |
//! |---|---|---|---|
//! | `file` | | yes | the trial's CSV in the same folder (a plain file name ending in `.csv`) |
//! | `sex` | | yes | `M`/`F` or `male`/`female` (de Leva's table, the exoskeleton template) |
//! | `height_m` | m | yes | stature, 1.0..=2.3 |
//! | `mass_kg` | kg | yes | body mass, 20..=300 |
//! | `speed_m_s` | m/s | yes | treadmill belt speed, 0.1..=3 |
//! | `leg_length_m` | m | no | hip joint centre to floor, 0.35..=0.65 of the stature |
//! | `stride_s` | s | no | stride time, 0.2..=20 |
//! | `cadence_steps_per_min` | steps/min | no | used when `stride_s` is blank (stride = 120 / cadence) |
//! | `subject`, `trial`, `age_group` | | no | labels for the report |
//!
//! Other columns (ages, sources, ...) are ignored. A blank `stride_s` and cadence is
//! estimated from the speed and the leg length ([`estimated_stride_s`]) and the report says so.
//! A row's problem is that row's (the other trials still run); a table without its required
//! columns, or not CSV at all, is the folder's.

use crate::error::{Error, Result};
use crate::leg::subject::Sex;

/// Most rows a `subjects.csv` may have.
pub const MAX_SUBJECT_ROWS: usize = 10_000;
/// The columns every `subjects.csv` must have.
pub const REQUIRED_SUBJECT_COLUMNS: [&str; 5] = ["file", "sex", "height_m", "mass_kg", "speed_m_s"];
/// A stride time and a cadence that disagree by more than this fraction are refused.
const STRIDE_CADENCE_TOLERANCE: f64 = 0.01;

/// Where a trial's stride time comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StrideSource {
    /// The row's `stride_s`.
    Given,
    /// 120 / the row's `cadence_steps_per_min`.
    Cadence,
    /// Neither: [`estimated_stride_s`] from the speed and the leg length.
    Estimated,
}

/// One row of a `subjects.csv`, checked.
#[derive(Debug, Clone, PartialEq)]
pub struct TrialRow {
    /// The row's line in the file (1-based; the header is line 1).
    pub line: usize,
    /// The trial's CSV (a file name in the table's folder).
    pub file: String,
    /// `subject` (may be empty).
    pub subject: String,
    /// `trial` (may be empty).
    pub trial: String,
    /// `age_group` (may be empty).
    pub group: String,
    /// The subject's sex.
    pub sex: Sex,
    /// Body mass (kg).
    pub mass_kg: f64,
    /// Stature (m).
    pub height_m: f64,
    /// Hip joint centre to floor (m), if given.
    pub leg_length_m: Option<f64>,
    /// Treadmill belt speed (m/s).
    pub speed_m_s: f64,
    /// Stride time (s).
    pub stride_s: f64,
    /// Where `stride_s` comes from.
    pub stride_from: StrideSource,
}

/// A stride time (s) from a treadmill speed (m/s) and a leg length (m), for a row that gives
/// neither stride nor cadence: the relation fitted to the 22 WBDS young adults' 132 treadmill
/// trials in Froude-scaled form, `cadence/60 sqrt(L/g) = 0.905 (v / sqrt(g L))^0.509` (log-SD
/// 0.056, about +-6 %; `assets/gait/README.md`, "Stride times used by exoleg": it gives subject
/// 02's built-in strides, 1.21 / 1.01 / 0.94 s).
pub fn estimated_stride_s(speed_m_s: f64, leg_length_m: f64) -> f64 {
    let g = crate::leg::model::GRAVITY_M_S2;
    let froude = speed_m_s / (g * leg_length_m).sqrt();
    let steps_per_s = 0.905 * froude.powf(0.509) / (leg_length_m / g).sqrt();
    2.0 / steps_per_s
}

/// A row of a `subjects.csv` as read: its line, the file it names (as written, possibly
/// empty), and the row checked.
#[derive(Debug)]
pub struct SubjectRow {
    /// The row's line in the file (1-based; the header is line 1).
    pub line: usize,
    /// The `file` column as written.
    pub file: String,
    /// The row, or why it is bad (naming the file, the row and the column).
    pub row: Result<TrialRow>,
}

/// Read a `subjects.csv` (`name` for messages): the table's own problems (not CSV, a required
/// column missing, too many rows) are the error; each row is checked on its own, its error
/// naming the file, its row and its column.
pub fn read_subjects(name: &str, text: &str) -> Result<Vec<SubjectRow>> {
    let mut rdr = csv::ReaderBuilder::new().trim(csv::Trim::All).from_reader(text.as_bytes());
    let headers = rdr.headers().map_err(|e| Error::input(name, "header", format!("malformed CSV: {e}")))?.clone();
    if let Some(missing) = REQUIRED_SUBJECT_COLUMNS.iter().find(|c| !headers.iter().any(|h| h == **c)) {
        return Err(Error::input(
            name,
            *missing,
            format!("missing column (a subjects.csv needs {})", REQUIRED_SUBJECT_COLUMNS.join(", ")),
        ));
    }
    let mut rows = Vec::new();
    for (i, rec) in rdr.records().enumerate() {
        let line = i + 2;
        if i >= MAX_SUBJECT_ROWS {
            return Err(Error::input(name, "rows", format!("more than {MAX_SUBJECT_ROWS} rows (the cap)")));
        }
        rows.push(match rec {
            Ok(rec) => {
                let file = headers.iter().position(|h| h == "file").and_then(|i| rec.get(i)).unwrap_or("");
                SubjectRow { line, file: file.to_string(), row: row(name, line, &headers, &rec) }
            }
            Err(e) => SubjectRow {
                line,
                file: String::new(),
                row: Err(Error::input(name, format!("row {line}"), format!("malformed CSV: {e}"))),
            },
        });
    }
    if rows.is_empty() {
        return Err(Error::input(name, "rows", "no trials: the table has a header and no rows"));
    }
    Ok(rows)
}

/// One row's fields by column name.
struct Fields<'a> {
    name: &'a str,
    line: usize,
    headers: &'a csv::StringRecord,
    rec: &'a csv::StringRecord,
}

impl Fields<'_> {
    fn bad(&self, column: &str, message: String) -> Error {
        Error::input(self.name, format!("row {}, {column}", self.line), message)
    }

    /// The text of `column` ("" when the table has no such column).
    fn text(&self, column: &str) -> &str {
        self.headers.iter().position(|h| h == column).and_then(|i| self.rec.get(i)).unwrap_or("")
    }

    /// `column` as a number in `lo..=hi` (`unit` for messages); None when blank and optional.
    fn number(&self, column: &str, lo: f64, hi: f64, unit: &str, required: bool) -> Result<Option<f64>> {
        let s = self.text(column);
        if s.is_empty() {
            return if required { Err(self.bad(column, "missing value".into())) } else { Ok(None) };
        }
        let v: f64 = s.parse().map_err(|_| self.bad(column, format!("not a number: {s:?}")))?;
        if !v.is_finite() || !(lo..=hi).contains(&v) {
            return Err(self.bad(column, format!("{s} {unit} is outside {lo}..={hi} {unit}")));
        }
        Ok(Some(v))
    }
}

fn row(name: &str, line: usize, headers: &csv::StringRecord, rec: &csv::StringRecord) -> Result<TrialRow> {
    let f = Fields { name, line, headers, rec };
    let file = f.text("file");
    let plain = !file.is_empty() && !file.contains(['/', '\\']) && file != ".." && file.ends_with(".csv");
    if !plain || file == "subjects.csv" {
        return Err(
            f.bad("file", format!("{file:?} is not a trial's CSV in this folder (a plain file name ending in .csv)"))
        );
    }
    let sex = match f.text("sex").to_ascii_lowercase().as_str() {
        "m" | "male" => Sex::Male,
        "f" | "female" => Sex::Female,
        other => return Err(f.bad("sex", format!("{other:?}: give M, F, male or female"))),
    };
    let need = |c: &str, lo: f64, hi: f64, unit: &str| f.number(c, lo, hi, unit, true).map(|v| v.unwrap_or(f64::NAN));
    let mass_kg = need("mass_kg", 20.0, 300.0, "kg")?;
    let height_m = need("height_m", 1.0, 2.3, "m")?;
    let speed_m_s = need("speed_m_s", 0.1, 3.0, "m/s")?;
    let leg_length_m = f.number("leg_length_m", 0.35 * height_m, 0.65 * height_m, "m", false)?;
    let stride = f.number("stride_s", 0.2, 20.0, "s", false)?;
    let cadence = f.number("cadence_steps_per_min", 6.0, 600.0, "steps/min", false)?;
    let (stride_s, stride_from) = match (stride, cadence) {
        (Some(s), Some(c)) if (s * c / 120.0 - 1.0).abs() > STRIDE_CADENCE_TOLERANCE => {
            return Err(f.bad(
                "stride_s",
                format!("{s} s contradicts cadence_steps_per_min = {c} (a stride of {:.4} s)", 120.0 / c),
            ))
        }
        (Some(s), _) => (s, StrideSource::Given),
        (None, Some(c)) => (120.0 / c, StrideSource::Cadence),
        (None, None) => {
            let body = crate::leg::subject::SubjectBody { mass_kg, height_m, leg_length_m, sex };
            (estimated_stride_s(speed_m_s, crate::leg::subject::leg_length_m(&body)), StrideSource::Estimated)
        }
    };
    Ok(TrialRow {
        line,
        file: file.to_string(),
        subject: f.text("subject").to_string(),
        trial: f.text("trial").to_string(),
        group: f.text("age_group").to_string(),
        sex,
        mass_kg,
        height_m,
        leg_length_m,
        speed_m_s,
        stride_s,
        stride_from,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Subject 02's built-in stride times are this estimate, rounded (her leg 0.865 m).
    #[test]
    fn the_estimate_gives_subject_02s_strides() {
        for (v, s) in [(0.88, 1.21), (1.25, 1.01), (1.44, 0.94)] {
            let e = estimated_stride_s(v, 0.865);
            assert!((e - s).abs() < 0.005, "{v} m/s: {e} s against {s}");
        }
    }

    #[test]
    fn rows_are_checked_one_by_one() {
        let text = "subject,file,sex,height_m,mass_kg,leg_length_m,speed_m_s,stride_s,cadence_steps_per_min\n\
                    1,a.csv,M,1.75,75,0.9,1.2,1.05,\n\
                    2,b.csv,f,1.6,0,,1.1,,\n\
                    3,c.csv,F,5,60,,1.1,,\n\
                    4,d.csv,F,1.6,60,,1.1,,120\n\
                    5,e.csv,F,1.6,60,,1.1,1.2,120\n\
                    6,../f.csv,F,1.6,60,,1.1,,\n\
                    7,g.csv,F,1.6,sixty,,1.1,,\n";
        let rows: Vec<Result<TrialRow>> =
            read_subjects("subjects.csv", text).unwrap().into_iter().map(|r| r.row).collect();
        let a = rows[0].as_ref().unwrap();
        assert_eq!((a.stride_s, a.stride_from, a.sex), (1.05, StrideSource::Given, Sex::Male));
        let err = |i: usize| rows[i].as_ref().unwrap_err().to_string();
        assert!(err(1).contains("row 3, mass_kg") && err(1).contains("outside"), "{}", err(1));
        assert!(err(2).contains("row 4, height_m"), "{}", err(2));
        let d = rows[3].as_ref().unwrap();
        assert_eq!((d.stride_s, d.stride_from), (1.0, StrideSource::Cadence));
        assert!(err(4).contains("row 6, stride_s") && err(4).contains("contradicts"), "{}", err(4));
        assert!(err(5).contains("row 7, file"), "{}", err(5));
        assert!(err(6).contains("row 8, mass_kg") && err(6).contains("not a number"), "{}", err(6));
        let e = read_subjects("subjects.csv", "file,sex,height_m,mass_kg\na.csv,M,1.7,70\n").unwrap_err();
        assert!(e.to_string().contains("speed_m_s"), "{e}");
    }
}
