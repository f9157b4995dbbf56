//! Instances from a table of events: `(instances :csv "hits.csv" :class collision
//! :start-column "time" :bind (:amp "force" :n_freq 50))` makes one instance per row,
//! so a physics simulation's collision log becomes a soundtrack.
//!
//! With `:frame-rate R` the start and stop columns hold frame numbers (an
//! animator's hit list): frame f starts at (f − first) / R seconds, `first` being
//! `:first-frame` (0 unless given; a Blender shot usually starts at frame 1).
//!
//! Each row becomes the form `(instance NAME (CLASS :param value …) :start s :stop e
//! :gain g)`, with the row's numbers in place of the column names, lowered like a
//! written one (its diagnostics point at the `instances` form).

use timbre_syntax::{Expr, ExprKind, Span};

use super::scene::Options;
use super::{Lowerer, Origin};
use timbre_diag::Diag;

const USAGE: &str = "(instances :csv \"hits.csv\" :class collision :start-column \"time\" :bind (:amp \"force\" :n_freq 50))";

/// Where a parameter's value comes from.
enum Value {
    Constant(Expr),
    Column(usize),
}

impl Lowerer<'_> {
    /// One instance per row of the CSV file of an `instances` form, added to the
    /// scene's instances.
    pub(crate) fn lower_instances(&mut self, form: &Expr, origin: &Origin) -> Result<(), Diag> {
        let items = form.as_list().unwrap_or_default();
        let options = self.options(
            &items[1..],
            "instances",
            &[
                "csv",
                "class",
                "start-column",
                "stop-column",
                "name-column",
                "bind",
                "gain",
                "source",
                "frame-rate",
                "first-frame",
                "declick",
            ],
            origin,
        )?;
        let required = |key: &str| {
            options.get(key).ok_or_else(|| {
                self.diag(
                    "timbre::bad-instances",
                    format!("`instances` needs `:{key}`"),
                    origin,
                )
                .label(form.span, format!("no :{key}"))
                .help(format!("write {USAGE}"))
            })
        };
        let (path_expr, class_expr) = (required("csv")?, required("class")?);
        required("start-column")?;
        let Some(class) = class_expr.as_symbol() else {
            return Err(self
                .diag(
                    "timbre::bad-instances",
                    "`:class` names a sound class",
                    origin,
                )
                .label(class_expr.span, "expected a name")
                .help(format!("write {USAGE}")));
        };
        let frames = self.frame_timing(&options, origin)?;
        let table = self.read_table(path_expr, origin)?;
        let column = |l: &Self, key: &str| -> Result<Option<usize>, Diag> {
            let Some(e) = options.get(key) else {
                return Ok(None);
            };
            let ExprKind::Str(name) = &e.kind else {
                return Err(l
                    .diag(
                        "timbre::bad-instances",
                        format!("`:{key}` is a column's name, in quotes"),
                        origin,
                    )
                    .label(e.span, "expected a string")
                    .help(format!("write :{key} \"time\"")));
            };
            table.column(name).map(Some).ok_or_else(|| {
                l.diag(
                    "timbre::bad-instances",
                    format!("the table has no column `{name}`"),
                    origin,
                )
                .label(e.span, "not a column")
                .help(format!("its columns are {}", table.header.join(", ")))
            })
        };
        let start_column = column(self, "start-column")?.unwrap_or_default();
        let stop_column = column(self, "stop-column")?;
        let name_column = column(self, "name-column")?;
        let binds = self.bindings(&options, &table, origin)?;
        for (row, cells) in table.rows.iter().enumerate() {
            self.check_load_time(path_expr.span, origin)?;
            let line = row + 2;
            let number = |l: &Self, index: usize| -> Result<f64, Diag> {
                let text = cells[index].trim();
                text.parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| {
                        l.diag(
                            "timbre::bad-instances",
                            format!(
                                "line {line}, column `{}`: `{text}` is not a number",
                                table.header[index]
                            ),
                            origin,
                        )
                        .label(path_expr.span, "this file")
                        .help("every cell that a parameter or a time reads must be a number")
                    })
            };
            let span = form.span;
            let num = |x: f64| Expr {
                kind: ExprKind::Number(x),
                span,
            };
            let sym = |s: &str, span: Span| Expr {
                kind: ExprKind::Symbol(s.to_owned()),
                span,
            };
            let key = |s: &str, span: Span| Expr {
                kind: ExprKind::Keyword(s.to_owned()),
                span,
            };
            let mut call = vec![sym(class, class_expr.span)];
            for (param, param_span, value) in &binds {
                call.push(key(param, *param_span));
                call.push(match value {
                    Value::Constant(e) => e.clone(),
                    Value::Column(index) => num(number(self, *index)?),
                });
            }
            let name = match name_column {
                Some(index) => cells[index].trim().to_owned(),
                None => format!("{class}-{}", row + 1),
            };
            let mut instance = vec![
                sym("instance", span),
                sym(&name, span),
                Expr {
                    kind: ExprKind::List(call),
                    span,
                },
                key("start", span),
                num(frames.seconds(number(self, start_column)?)),
            ];
            if let Some(index) = stop_column {
                instance.push(key("stop", span));
                instance.push(num(frames.seconds(number(self, index)?)));
            }
            for option in ["gain", "source", "declick"] {
                if let Some(e) = options.get(option) {
                    instance.push(key(option, span));
                    instance.push(e.clone());
                }
            }
            let instance = Expr {
                kind: ExprKind::List(instance),
                span,
            };
            let instance = self.lower_instance(&instance, origin)?;
            self.scene.instances.push(instance);
        }
        Ok(())
    }

    /// How the start and stop columns count time: seconds, or frames with
    /// `:frame-rate` (and `:first-frame`).
    pub(super) fn frame_timing(
        &mut self,
        options: &Options<'_>,
        origin: &Origin,
    ) -> Result<Frames, Diag> {
        let rate = match options.get("frame-rate") {
            Some(e) => {
                let rate = self.constant_option(e, "the frame rate", origin)?;
                if !(rate > 0.0 && rate.is_finite()) {
                    return Err(self
                        .diag(
                            "timbre::bad-instances",
                            format!("frame rate {rate} is not positive"),
                            origin,
                        )
                        .label(e.span, "frames per second")
                        .help("write e.g. :frame-rate 24 (frame f starts at f/24 s)"));
                }
                Some(rate)
            }
            None => None,
        };
        let first = match (options.get("first-frame"), rate) {
            (Some(e), None) => {
                return Err(self
                    .diag(
                        "timbre::bad-instances",
                        "`:first-frame` counts frames, and the times are in seconds",
                        origin,
                    )
                    .label(e.span, "no :frame-rate")
                    .help("add :frame-rate 24 to read the start column as frame numbers"))
            }
            (Some(e), Some(_)) => self.constant_option(e, "the first frame", origin)?,
            (None, _) => 0.0,
        };
        Ok(Frames { rate, first })
    }

    /// `:bind (:param "column" :param constant …)`.
    fn bindings(
        &mut self,
        options: &Options<'_>,
        table: &Table,
        origin: &Origin,
    ) -> Result<Vec<(String, Span, Value)>, Diag> {
        let Some(bind) = options.get("bind") else {
            return Ok(vec![]);
        };
        let items = bind.as_list().unwrap_or_default();
        let mut binds = vec![];
        for pair in items.chunks(2) {
            let (ExprKind::Keyword(param), Some(value)) = (&pair[0].kind, pair.get(1)) else {
                return Err(self
                    .diag(
                        "timbre::bad-instances",
                        "`:bind` pairs a parameter with a column or a value",
                        origin,
                    )
                    .label(pair[0].span, "expected :param then a value")
                    .help("write :bind (:amp \"force\" :n_freq 50)"));
            };
            let value = match &value.kind {
                ExprKind::Str(name) => match table.column(name) {
                    Some(index) => Value::Column(index),
                    None => {
                        return Err(self
                            .diag(
                                "timbre::bad-instances",
                                format!("the table has no column `{name}`"),
                                origin,
                            )
                            .label(value.span, "not a column")
                            .help(format!("its columns are {}", table.header.join(", "))))
                    }
                },
                _ => Value::Constant(value.clone()),
            };
            binds.push((param.clone(), pair[0].span, value));
        }
        Ok(binds)
    }

    /// The CSV file of `path_expr`, read through the loader.
    fn read_table(&mut self, path_expr: &Expr, origin: &Origin) -> Result<Table, Diag> {
        let ExprKind::Str(path) = &path_expr.kind else {
            return Err(self
                .diag(
                    "timbre::bad-instances",
                    "`:csv` is a file name, in quotes",
                    origin,
                )
                .label(path_expr.span, "expected a string")
                .help(format!("write {USAGE}")));
        };
        let unreadable = |l: &Self, why: String| {
            l.diag(
                "timbre::csv-unreadable",
                format!("cannot read `{path}`: {why}"),
                origin,
            )
            .label(path_expr.span, "this file")
            .help(
                "paths are relative to the file that names them; the file is CSV with a header row",
            )
        };
        let (_, bytes) = self
            .options
            .loader
            .load(path, origin.dir.as_deref())
            .map_err(|e| unreadable(self, e.to_string()))?;
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(true)
            .trim(csv::Trim::All)
            .from_reader(bytes.as_slice());
        let header: Vec<String> = reader
            .headers()
            .map_err(|e| unreadable(self, e.to_string()))?
            .iter()
            .map(|h| h.trim_matches('"').to_owned())
            .collect();
        let mut rows = vec![];
        for record in reader.records() {
            self.check_load_time(path_expr.span, origin)?;
            let record = record.map_err(|e| unreadable(self, e.to_string()))?;
            rows.push(record.iter().map(str::to_owned).collect());
        }
        Ok(Table { header, rows })
    }
}

/// The timing of the start and stop columns.
pub(super) struct Frames {
    /// Frames per second, or `None` for times in seconds.
    pub rate: Option<f64>,
    /// The frame at scene time 0.
    pub first: f64,
}

impl Frames {
    fn seconds(&self, cell: f64) -> f64 {
        match self.rate {
            Some(rate) => (cell - self.first) / rate,
            None => cell,
        }
    }
}

/// A CSV file: its header and its rows of cells (each as long as the header).
struct Table {
    header: Vec<String>,
    rows: Vec<Vec<String>>,
}

impl Table {
    fn column(&self, name: &str) -> Option<usize> {
        self.header.iter().position(|h| h == name)
    }
}
