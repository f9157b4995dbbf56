//! `timbre fmt`: lays out .tt files in the canonical layout
//! (`timbre_syntax::format_source`), keeping their comments.

use std::path::PathBuf;

use clap::Args;

use crate::{print_diagnostics, Failure};

#[derive(Args, Debug)]
pub struct FmtArgs {
    /// The .tt files to lay out; `-` reads standard input.
    #[arg(required = true)]
    files: Vec<PathBuf>,

    /// Rewrite each file in place (written to a temporary file, then renamed over it,
    /// keeping its permissions) instead of printing it.
    #[arg(long, conflicts_with = "check")]
    write: bool,

    /// Print nothing; name the files that are not in the canonical layout and fail
    /// if there are any (for CI).
    #[arg(long)]
    check: bool,
}

pub fn fmt(args: FmtArgs) -> Result<(), Failure> {
    let mut unformatted = vec![];
    for path in &args.files {
        let stdin = path.as_os_str() == "-";
        if stdin && args.write {
            return Err(Failure::Message(
                "--write rewrites files: standard input has none (print it instead)".into(),
            ));
        }
        let text = read(path, stdin)?;
        let name = if stdin {
            "<stdin>".to_owned()
        } else {
            path.display().to_string()
        };
        let formatted = timbre_syntax::format_source(&text).map_err(|errors| {
            let source = timbre_ir::SourceFile::new(name.clone(), text.as_str());
            let diags: Vec<_> = (errors.iter()).map(|e| e.diag(&source)).collect();
            print_diagnostics(diags);
            Failure::Message(format!("`{name}` has syntax errors: it is left as it is"))
        })?;
        if args.check {
            if formatted != text {
                println!("{name}");
                unformatted.push(name);
            }
        } else if args.write {
            if formatted != text {
                // The file replaces itself: the one output that may be its own input.
                crate::output::replace_file(path, formatted.as_bytes(), &[])
                    .map_err(Failure::Message)?;
            }
        } else {
            print!("{formatted}");
        }
    }
    match unformatted.len() {
        0 => Ok(()),
        1 => Err(Failure::Message(format!(
            "`{}` is not in the canonical layout: `timbre fmt --write` lays it out",
            unformatted[0]
        ))),
        n => Err(Failure::Message(format!(
            "{n} files are not in the canonical layout (named above): `timbre fmt --write` lays them out"
        ))),
    }
}

fn read(path: &std::path::Path, stdin: bool) -> Result<String, Failure> {
    let cannot = |e: &dyn std::fmt::Display| {
        Failure::Message(format!("cannot read `{}`: {e}", path.display()))
    };
    let limit = timbre::Limits::default().script_bytes();
    let bytes = if stdin {
        crate::input::read_stdin(limit).map_err(|e| cannot(&e))?
    } else {
        timbre_lang::read_bounded(path, limit).map_err(|e| cannot(&e))?
    };
    String::from_utf8(bytes).map_err(|_| cannot(&"it is not UTF-8 text"))
}
