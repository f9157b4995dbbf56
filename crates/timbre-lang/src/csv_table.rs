//! Keyframe tracks read from a column of a CSV file exported from an animation
//! package, timed either by a frame rate (frame `k`, counting from 0, is at `k / rate`
//! seconds) or by another column of times in seconds.
//!
//! ```
//! use timbre_ir::keyframes::{Interpolation, KeyframeTrack};
//! use timbre_lang::csv_table::{keyframes_from_csv, CsvTime};
//!
//! let csv = "frame,force\n0,0.0\n1,2.0\n2,1.0\n";
//! let track = keyframes_from_csv(csv, "force", CsvTime::FrameRate(24.0), Interpolation::Linear)
//!     .unwrap();
//! assert_eq!(track.times(), &[0.0, 1.0 / 24.0, 2.0 / 24.0]);
//! assert_eq!(track.value(0.5 / 24.0), 1.0);
//! assert_eq!(track.value(10.0), 1.0);
//! ```

use timbre_ir::keyframes::{Interpolation, KeyframeError, KeyframeTrack};

/// How [`keyframes_from_csv`] finds the time of each row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CsvTime<'a> {
    /// Row `k` of the data (counting from 0) is at `k / rate` seconds.
    FrameRate(f64),
    /// The named column holds each row's time in seconds; it must be strictly
    /// increasing.
    Column(&'a str),
}

/// A track read from column `column` of the CSV `text`.
///
/// The first row is the header and names the columns (quoted names are fine);
/// the separator is a comma; spaces around cells and names are ignored, and so
/// are quotes around a whole cell even after a space (`a, "b"`); line
/// endings may be LF or CRLF, and a UTF-8 byte-order mark is skipped. Every row
/// must have as many cells as the header. `time` gives each row's time: by frame
/// rate (row `k` of the data at `k / rate` seconds) or from another column.
///
/// Errors: [`KeyframeError::ColumnNotFound`] (listing the columns there are),
/// [`KeyframeError::BadNumber`] for an empty, non-numeric or non-finite cell in a
/// column that is used, [`KeyframeError::RowOutOfOrder`] for a time column that
/// is not strictly increasing, [`KeyframeError::BadFrameRate`],
/// [`KeyframeError::Empty`] when there are no data rows, and
/// [`KeyframeError::Csv`] for text that is not CSV. Row numbers in errors are line
/// numbers of the file (header = 1; see [`KeyframeError`]).
pub fn keyframes_from_csv(
    text: &str,
    column: &str,
    time: CsvTime<'_>,
    interpolation: Interpolation,
) -> Result<KeyframeTrack, KeyframeError> {
    if let CsvTime::FrameRate(rate) = time {
        if !(rate.is_finite() && rate > 0.0) {
            return Err(KeyframeError::BadFrameRate { rate });
        }
    }
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .delimiter(b',')
        .trim(csv::Trim::All)
        .flexible(false)
        .from_reader(text.as_bytes());
    let headers = reader.headers().map_err(|e| csv_error(text, e))?.clone();
    let find = |name: &str| -> Result<usize, KeyframeError> {
        headers
            .iter()
            .position(|h| unquote(h) == name)
            .ok_or_else(|| KeyframeError::ColumnNotFound {
                column: name.to_owned(),
                available: list_columns(&headers),
            })
    };
    let value_column = find(column)?;
    let time_column = match time {
        CsvTime::Column(name) => Some(find(name)?),
        CsvTime::FrameRate(_) => None,
    };

    let mut times = Vec::new();
    let mut values = Vec::new();
    let mut record = csv::StringRecord::new();
    let mut previous: Option<f64> = None;
    while reader
        .read_record(&mut record)
        .map_err(|e| csv_error(text, e))?
    {
        // Only worked out for an error: counting lines is O(file size).
        let row = || {
            record
                .position()
                .map_or(times.len() + 2, |p| line_at(text, p.byte()))
        };
        let cell = |index: usize| -> Result<f64, KeyframeError> {
            let text = unquote(record.get(index).unwrap_or(""));
            match text.parse::<f64>() {
                Ok(x) if x.is_finite() => Ok(x),
                _ => Err(KeyframeError::BadNumber {
                    row: row(),
                    text: text.to_owned(),
                }),
            }
        };
        let value = cell(value_column)?;
        let t = match (time_column, time) {
            (Some(index), _) => {
                let t = cell(index)?;
                if let Some(previous) = previous {
                    if t <= previous {
                        return Err(KeyframeError::RowOutOfOrder {
                            row: row(),
                            time: t,
                            previous,
                        });
                    }
                }
                previous = Some(t);
                t
            }
            (None, CsvTime::FrameRate(rate)) => times.len() as f64 / rate,
            (None, CsvTime::Column(_)) => unreachable!("a time column was looked up"),
        };
        times.push(t);
        values.push(value);
    }
    // Frame times are k / rate: strictly increasing and finite for any positive
    // finite rate and any realistic row count, so `new` only reports `Empty` here.
    KeyframeTrack::new(times, values, interpolation)
}

/// A trimmed cell without one pair of surrounding double quotes, if it has them.
///
/// Strict CSV only treats a quote as opening a quoted cell right after the comma, so
/// `a, "b"` (with a space) reads as the cell `"b"` quotes and all; exporters that
/// write such files mean `b`. (A cell quoted properly has lost its quotes already.)
fn unquote(cell: &str) -> &str {
    match cell.strip_prefix('"').and_then(|c| c.strip_suffix('"')) {
        Some(inner) => inner.trim(),
        None => cell,
    }
}

fn list_columns(headers: &csv::StringRecord) -> String {
    if headers.is_empty() {
        return "none".to_owned();
    }
    headers
        .iter()
        .map(|h| format!("`{}`", unquote(h)))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The 1-based line number of the record that the `csv` crate says starts at byte
/// `byte` of `text`. (The crate's own line count skips blank lines, and its byte
/// position is before the blank lines it skips, so they are skipped here too.)
fn line_at(text: &str, byte: u64) -> usize {
    let bytes = text.as_bytes();
    let mut end = usize::try_from(byte).map_or(bytes.len(), |b| b.min(bytes.len()));
    while end < bytes.len() && matches!(bytes[end], b'\r' | b'\n') {
        end += 1;
    }
    1 + bytes[..end].iter().filter(|&&b| b == b'\n').count()
}

fn csv_error(text: &str, error: csv::Error) -> KeyframeError {
    let line = error.position().map(|p| line_at(text, p.byte()));
    let message = match error.kind() {
        csv::ErrorKind::UnequalLengths {
            expected_len, len, ..
        } => format!("a row has {len} cells but the header has {expected_len}"),
        csv::ErrorKind::Utf8 { .. } => "the text is not valid UTF-8".to_owned(),
        _ => error.to_string(),
    };
    match line {
        Some(line) => KeyframeError::Csv(format!("line {line}: {message}")),
        None => KeyframeError::Csv(message),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn csv(text: &str, column: &str, time: CsvTime<'_>) -> Result<KeyframeTrack, KeyframeError> {
        keyframes_from_csv(text, column, time, Interpolation::Linear)
    }

    #[test]
    fn csv_frame_rate_timing() {
        let text = "frame,force,angle\n1,0.5,10\n2,1.5,20\n3,-2,30\n4,4e-1,40\n";
        let tr = csv(text, "force", CsvTime::FrameRate(24.0)).unwrap();
        assert_eq!(tr.times(), &[0.0, 1.0 / 24.0, 2.0 / 24.0, 3.0 / 24.0]);
        assert_eq!(tr.values(), &[0.5, 1.5, -2.0, 0.4]);
        assert_eq!(tr.value(0.5 / 24.0), 1.0);
        let angle = csv(text, "angle", CsvTime::FrameRate(30.0)).unwrap();
        assert_eq!(angle.times()[3], 0.1);
        assert_eq!(angle.values(), &[10.0, 20.0, 30.0, 40.0]);
    }

    #[test]
    fn csv_time_column() {
        let text = "time,force\n0.5,1\n0.75,2\n2,0\n";
        let tr = keyframes_from_csv(text, "force", CsvTime::Column("time"), Interpolation::Step)
            .unwrap();
        assert_eq!(tr.times(), &[0.5, 0.75, 2.0]);
        assert_eq!(tr.values(), &[1.0, 2.0, 0.0]);
        assert_eq!(tr.value(1.0), 2.0);
        assert_eq!(tr.interpolation(), Interpolation::Step);

        let err = csv(
            "time,force\n0,1\n1,2\n1,3\n",
            "force",
            CsvTime::Column("time"),
        )
        .unwrap_err();
        assert_eq!(
            err,
            KeyframeError::RowOutOfOrder {
                row: 4,
                time: 1.0,
                previous: 1.0
            }
        );
        assert_eq!(
            err.to_string(),
            "row 4: time 1 s is not after the row before it (1 s)"
        );
    }

    #[test]
    fn csv_column_not_found_lists_the_columns() {
        let text = "time,force,\"rot x\"\n0,1,2\n";
        let err = csv(text, "forse", CsvTime::FrameRate(24.0)).unwrap_err();
        assert_eq!(
            err,
            KeyframeError::ColumnNotFound {
                column: "forse".into(),
                available: "`time`, `force`, `rot x`".into()
            }
        );
        assert_eq!(
            err.to_string(),
            "column `forse` not found; the columns are `time`, `force`, `rot x`"
        );
        // The time column is looked up too.
        let err = csv(text, "force", CsvTime::Column("seconds")).unwrap_err();
        assert!(
            matches!(err, KeyframeError::ColumnNotFound { ref column, .. } if column == "seconds")
        );
    }

    #[test]
    fn csv_bad_number_reports_the_row() {
        let text = "time,force\n0,1\n1,two\n2,3\n";
        let err = csv(text, "force", CsvTime::FrameRate(24.0)).unwrap_err();
        assert_eq!(
            err,
            KeyframeError::BadNumber {
                row: 3,
                text: "two".into()
            }
        );
        assert_eq!(err.to_string(), "row 3: `two` is not a number");
        // Empty cells, non-finite numbers and bad times are errors too.
        let err = csv("time,force\n0,1\n1,\n", "force", CsvTime::FrameRate(24.0)).unwrap_err();
        assert_eq!(
            err,
            KeyframeError::BadNumber {
                row: 3,
                text: "".into()
            }
        );
        let err = csv(
            "time,force\n0,1\n1,NaN\n",
            "force",
            CsvTime::FrameRate(24.0),
        )
        .unwrap_err();
        assert_eq!(
            err,
            KeyframeError::BadNumber {
                row: 3,
                text: "NaN".into()
            }
        );
        let err = csv(
            "time,force\n0,1\nsoon,2\n",
            "force",
            CsvTime::Column("time"),
        )
        .unwrap_err();
        assert_eq!(
            err,
            KeyframeError::BadNumber {
                row: 3,
                text: "soon".into()
            }
        );
        // A cell in a column that is not used may be anything.
        let tr = csv(
            "note,force\nstart,1\n,2\n",
            "force",
            CsvTime::FrameRate(24.0),
        )
        .unwrap();
        assert_eq!(tr.values(), &[1.0, 2.0]);
    }

    #[test]
    fn csv_quoting_line_endings_and_whitespace() {
        let text =
            "\u{feff}\"time\" ,\"force, x\"\r\n  0 ,  1.5 \r\n\r\n 0.5,\t-2\r\n1 ,\" 3 \"\r\n";
        let tr = csv(text, "force, x", CsvTime::Column("time")).unwrap();
        assert_eq!(tr.times(), &[0.0, 0.5, 1.0]);
        assert_eq!(tr.values(), &[1.5, -2.0, 3.0]);
        // Some exporters put a space before an opening quote, which strict CSV reads
        // as a literal quote: a pair of quotes around a whole trimmed cell is dropped.
        let text = "\"time\", \"force\"\n0, \"1\"\n1, 2\n";
        let tr = csv(text, "force", CsvTime::Column("time")).unwrap();
        assert_eq!(tr.values(), &[1.0, 2.0]);
        let err = csv(text, "forse", CsvTime::Column("time")).unwrap_err();
        assert_eq!(
            err.to_string(),
            "column `forse` not found; the columns are `time`, `force`"
        );
        // No trailing newline, CR-only blank lines are skipped too.
        let tr = csv("a,b\n1,2\n3,4", "b", CsvTime::FrameRate(2.0)).unwrap();
        assert_eq!(tr.times(), &[0.0, 0.5]);
        assert_eq!(tr.values(), &[2.0, 4.0]);
        // Row numbers are line numbers, so blank lines count.
        let err = csv("a\n1\n\nx\n", "a", CsvTime::FrameRate(1.0)).unwrap_err();
        assert_eq!(
            err,
            KeyframeError::BadNumber {
                row: 4,
                text: "x".into()
            }
        );
    }

    #[test]
    fn csv_other_errors() {
        assert_eq!(
            csv("time,force\n", "force", CsvTime::FrameRate(24.0)),
            Err(KeyframeError::Empty)
        );
        assert_eq!(
            csv("", "force", CsvTime::FrameRate(24.0)),
            Err(KeyframeError::ColumnNotFound {
                column: "force".into(),
                available: "none".into()
            })
        );
        for rate in [0.0, -24.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                csv("force\n1\n", "force", CsvTime::FrameRate(rate)),
                Err(KeyframeError::BadFrameRate { .. })
            ));
        }
        let err = csv("a,b\n1,2\n3\n", "b", CsvTime::FrameRate(24.0)).unwrap_err();
        assert_eq!(
            err,
            KeyframeError::Csv("line 3: a row has 1 cells but the header has 2".into())
        );
    }
}
