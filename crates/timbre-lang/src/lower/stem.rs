//! The stem an instance is heard in (`timbre render --stems`): `:stem "Cube"` names
//! its object, `:stem ("Cube" "impacts")` its object and kind; without `:stem`, an
//! instance placed on a source that rides a glTF node (`(source s :object "Cube")`),
//! or at one (`:at "Ball"`, as `events` places what it finds), is that node's, and
//! any other is unlabelled.

use std::sync::Arc;

use timbre_diag::Diag;
use timbre_ir::Stem;
use timbre_syntax::{Expr, ExprKind};

use super::{Lowerer, Origin};

const USAGE: &str = ":stem \"Cube\", or :stem (\"Cube\" \"impacts\") for an object and a kind";

impl Lowerer<'_> {
    /// The stem of an instance with `:stem` = `stem` (if given), placed on the
    /// source named `source` or `at` a place (if either).
    pub(crate) fn instance_stem(
        &self,
        stem: Option<&Expr>,
        source: Option<&Expr>,
        at: Option<&Expr>,
        origin: &Origin,
    ) -> Result<Stem, Diag> {
        let Some(stem) = stem else {
            let ridden = source
                .and_then(Expr::as_symbol)
                .and_then(|name| self.scene.space.source_object(name));
            let object = ridden.or_else(|| match at.map(|e| &e.kind) {
                Some(ExprKind::Str(node)) => Some(Arc::from(node.as_str())),
                _ => None,
            });
            return Ok(Stem { object, kind: None });
        };
        match &stem.kind {
            ExprKind::Str(_) => Ok(Stem {
                object: Some(self.stem_name(stem, origin)?),
                kind: None,
            }),
            ExprKind::List(items) if items.len() == 2 => Ok(Stem {
                object: Some(self.stem_name(&items[0], origin)?),
                kind: Some(self.stem_name(&items[1], origin)?),
            }),
            _ => Err(self
                .diag(
                    "timbre::bad-stem",
                    format!("`:stem` takes a name in quotes, not {}", stem.describe()),
                    origin,
                )
                .label(stem.span, "not a stem")
                .help(format!("write {USAGE}"))),
        }
    }

    /// One name of a stem: a string that is not blank.
    fn stem_name(&self, e: &Expr, origin: &Origin) -> Result<Arc<str>, Diag> {
        let message = match &e.kind {
            ExprKind::Str(name) if !name.trim().is_empty() => return Ok(Arc::from(name.as_str())),
            ExprKind::Str(_) => "a stem's name is blank".to_owned(),
            _ => format!("a stem is named by a name in quotes, not {}", e.describe()),
        };
        Err(self
            .diag("timbre::bad-stem", message, origin)
            .label(e.span, "expected a name in quotes")
            .help(format!("write {USAGE}")))
    }
}
