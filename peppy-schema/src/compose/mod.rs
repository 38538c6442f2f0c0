//! Composed launchers: one `launcher/v1` file describing a family of
//! stacks. `components` are axes of options, each option a list of
//! fragments (inline or `launcher_fragment/v1` files) that add deployments,
//! core nodes and adjustments; `adjustments` edit the instances a selection
//! deploys; `constraints` refuse selections nobody should run. A selection
//! (from `--with` words) is composed into the flat launcher every other
//! command reads: its text is printed, then parsed again as an ordinary
//! flat launcher, so a composed stack and the file `resolve` prints are
//! checked by the same code.
//!
//! Fragments cannot reference other fragments, so composition has no
//! cycles to detect.

mod flatten;
mod parse;
mod print;
mod select;
mod space;

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::diag::Diagnostics;
use crate::json::Node;
use crate::launcher::LauncherDoc;
use crate::read::Loc;
use crate::source::SourceFile;

pub(crate) use parse::is_composed;
pub use space::{CompositionCheck, SelectionVerdict};

/// Selections a composed launcher may have before `repo index --check`
/// stops checking every one of them (and says so).
pub const MAX_SELECTIONS: usize = 512;

/// Selections [`Composition::selections`] lists at most.
pub const MAX_LISTED_SELECTIONS: usize = 65_536;

/// A launcher file read for composition: a flat launcher (either spelling),
/// or a composed `launcher/v1` with every fragment of every option loaded.
#[derive(Debug, Clone)]
pub struct Composition {
    /// The launcher's text.
    pub file: Arc<SourceFile>,
    /// The axes, in declaration order (empty for a flat launcher).
    pub axes: Vec<Axis>,
    /// `constraints`, in declaration order.
    pub constraints: Vec<Constraint>,
    /// `adjustments` of the base, in declaration order.
    pub adjustments: Vec<Adjustment>,
    /// Where `components` is (a flat launcher: the document).
    pub(crate) components_loc: Loc,
    /// The flat launcher as loaded, for a launcher without `components`.
    pub(crate) flat: Option<LauncherDoc>,
    /// The document's root.
    pub(crate) root: Node,
    /// Every fragment of every option, each file once.
    pub(crate) fragments: Vec<Fragment>,
    /// Base deployments (their nodes), in order.
    pub(crate) base_deployments: Vec<Node>,
    /// Base `core_nodes`, if written.
    pub(crate) base_core_nodes: Option<Node>,
}

/// One axis of `components`.
#[derive(Debug, Clone)]
pub struct Axis {
    /// Its name.
    pub name: String,
    /// Its options, in declaration order.
    pub options: Vec<AxisOption>,
    /// `default`: the option taken when no `--with` names this axis.
    pub default: Option<String>,
    /// `optional`: without a selection the axis stays unfilled.
    pub optional: bool,
    /// `provides`: instance ids every option defines.
    pub provides: Vec<String>,
    /// Where the axis's name is.
    pub loc: Loc,
}

/// One option of an axis.
#[derive(Debug, Clone)]
pub struct AxisOption {
    /// Its name.
    pub name: String,
    /// Where its key is.
    pub loc: Loc,
    /// Its fragments (indices into the composition's fragments), merged in
    /// this order.
    pub(crate) fragments: Vec<usize>,
}

/// A loaded fragment: a file, or an inline option body.
#[derive(Debug, Clone)]
pub(crate) struct Fragment {
    /// The fragment's text (the launcher's, for an inline one).
    pub(crate) file: Arc<SourceFile>,
    /// How reports name it: the path as written, or ``inline option `axis.option` ``.
    pub(crate) origin: String,
    /// Its directory relative to the launcher's, for `local` sources.
    pub(crate) dir: PathBuf,
    /// Its deployments' nodes.
    pub(crate) deployments: Vec<Node>,
    /// Its `core_nodes`, if written.
    pub(crate) core_nodes: Option<Node>,
    /// Its adjustments, in order.
    pub(crate) adjustments: Vec<Adjustment>,
}

/// One `axis: option` pair of a `when`, `requires` or `forbids` map.
#[derive(Debug, Clone)]
pub struct Pair {
    /// The axis.
    pub axis: String,
    /// The option.
    pub option: String,
    /// Where the pair is.
    pub loc: Loc,
}

/// One `adjustments` entry, from the base or a fragment.
#[derive(Debug, Clone)]
pub struct Adjustment {
    /// The instance it edits.
    pub target: String,
    /// `when`: the selection it needs (empty: always).
    pub when: Vec<Pair>,
    /// `set_arguments`, in order.
    pub(crate) set_arguments: Vec<(String, Node)>,
    /// `set_links`, in order.
    pub(crate) set_links: Vec<(String, Node)>,
    /// `add_links`, in order.
    pub(crate) add_links: Vec<(String, Vec<String>)>,
    /// `unset_links`, in order.
    pub(crate) unset_links: Vec<String>,
    /// Where it comes from, for reports: a fragment's path as written,
    /// ``inline option `axis.option` `` or `FILE (base)`.
    pub origin: String,
    /// Where the entry is.
    pub loc: Loc,
}

/// One `constraints` entry.
#[derive(Debug, Clone)]
pub struct Constraint {
    /// `when`: the selections it judges (empty: all).
    pub when: Vec<Pair>,
    /// `requires`: alternatives, one of which must match.
    pub requires: Vec<Vec<Pair>>,
    /// `forbids`: maps none of which may match.
    pub forbids: Vec<Vec<Pair>>,
    /// Why, as the author wrote it.
    pub reason: String,
    /// Where the entry is.
    pub loc: Loc,
}

/// How an axis of a selection came to be filled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChoiceSource {
    /// Named by `--with`.
    Explicit,
    /// The axis's `default`.
    Default,
    /// An optional axis nothing selected.
    Unfilled,
}

/// One axis of a selection.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Choice {
    /// The axis.
    pub axis: String,
    /// The option; `None` for an unfilled optional axis.
    pub option: Option<String>,
    /// How it was chosen.
    pub source: ChoiceSource,
}

/// A selection: one choice per axis, in declaration order.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Selection {
    /// The choices.
    pub choices: Vec<Choice>,
}

impl Selection {
    /// The option chosen on `axis`, if any.
    pub fn option_of(&self, axis: &str) -> Option<&str> {
        self.choices
            .iter()
            .find(|c| c.axis == axis)
            .and_then(|c| c.option.as_deref())
    }

    /// The selection as `--with` words (`axis=option,...`; unfilled axes
    /// left out), which select it again.
    pub fn with_words(&self) -> String {
        self.choices
            .iter()
            .filter_map(|c| c.option.as_ref().map(|o| format!("{}={o}", c.axis)))
            .collect::<Vec<_>>()
            .join(",")
    }

    fn matches(&self, map: &[Pair]) -> bool {
        map.iter()
            .all(|p| self.option_of(&p.axis) == Some(p.option.as_str()))
    }
}

/// The echo: `axis=option`, `axis=option (default)`, `axis=(off)`, axes in
/// declaration order, two spaces apart.
impl fmt::Display for Selection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, c) in self.choices.iter().enumerate() {
            if i > 0 {
                f.write_str("  ")?;
            }
            match (&c.option, c.source) {
                (Some(o), ChoiceSource::Default) => write!(f, "{}={o} (default)", c.axis)?,
                (Some(o), _) => write!(f, "{}={o}", c.axis)?,
                (None, _) => write!(f, "{}=(off)", c.axis)?,
            }
        }
        Ok(())
    }
}

/// A launcher resolved for one selection: the flat launcher every command
/// uses, its text, and what composing it did.
#[derive(Debug, Clone)]
pub struct Resolved {
    /// The flat launcher (rules 7 and 8 of the whole stack are left to the
    /// binding plan, as for any launcher read for a plan).
    pub launcher: LauncherDoc,
    /// The flat launcher as `launcher/v1` JSON5 (a `launcher_v1` launcher:
    /// its own text); it parses again as the same flat launcher.
    pub text: String,
    /// What composing did.
    pub report: ResolveReport,
    /// Warnings.
    pub warnings: Diagnostics,
}

/// What composing a selection did, for `resolve`'s report.
#[derive(Debug, Clone, Default)]
pub struct ResolveReport {
    /// The selection; `None` for a flat launcher.
    pub selection: Option<Selection>,
    /// Adjustments that changed something, in the order applied.
    pub applied: Vec<AppliedChange>,
    /// Adjustments skipped, with why.
    pub skipped: Vec<SkippedAdjustment>,
    /// How many constraints the selection was checked against.
    pub constraints_checked: usize,
}

/// One change an adjustment made.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AppliedChange {
    /// The instance.
    pub target: String,
    /// `arguments.KEY` or `links.SLOT`.
    pub field: String,
    /// `OLD -> NEW`, `+ TARGET`, or `removed (was OLD)` (values as compact
    /// JSON, `(absent)` when there was none).
    pub change: String,
    /// The adjustment's origin.
    pub origin: String,
}

/// An adjustment that did not apply to this selection.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SkippedAdjustment {
    /// The instance it targets.
    pub target: String,
    /// `target is not in this selection` or `guard a=o is not met`.
    pub reason: String,
    /// The adjustment's origin.
    pub origin: String,
}

impl ResolveReport {
    /// The report's lines, as `resolve` prints them on stderr.
    pub fn lines(&self) -> Vec<String> {
        let mut out = Vec::new();
        match &self.selection {
            Some(s) => out.push(format!("components: {s}")),
            None => out.push("components: (flat launcher)".to_string()),
        }
        if !self.applied.is_empty() {
            out.push("adjustments applied:".to_string());
            for a in &self.applied {
                out.push(format!(
                    "  {}.{}: {}  ({})",
                    a.target, a.field, a.change, a.origin
                ));
            }
        }
        if !self.skipped.is_empty() {
            out.push("adjustments skipped:".to_string());
            for s in &self.skipped {
                out.push(format!("  {}: {}  ({})", s.target, s.reason, s.origin));
            }
        }
        if self.selection.is_some() {
            out.push(format!(
                "constraints checked: {} hold",
                self.constraints_checked
            ));
        }
        out
    }
}

impl Composition {
    /// Reads the launcher at `path` and, when it is composed, every
    /// fragment of every option.
    pub fn load(path: &Path) -> Result<Composition, Diagnostics> {
        let (file, _) = SourceFile::read(path).map_err(|d| Diagnostics::from(*d))?;
        parse::parse_composition(&file)
    }

    /// [`Composition::load`] from text; fragment files are read relative
    /// to `path`'s directory.
    pub fn parse(
        path: impl Into<PathBuf>,
        text: impl Into<String>,
    ) -> Result<Composition, Diagnostics> {
        parse::parse_composition(&SourceFile::new(path, text))
    }

    /// Whether the launcher has `components`.
    pub fn is_composed(&self) -> bool {
        self.flat.is_none()
    }

    /// The selection `--with` words give (each `option` or `axis=option`,
    /// comma-separated, in any number of words): unnamed axes take their
    /// default, optional ones stay unfilled.
    pub fn select(&self, words: &[String]) -> Result<Selection, Diagnostics> {
        select::select(self, words)
    }

    /// The first constraint `selection` violates, as its located error.
    pub fn judge(&self, selection: &Selection) -> Result<(), Diagnostics> {
        select::judge(self, selection)
    }

    /// Every selection the axes allow (each optional axis also unfilled),
    /// in order, with the constraint that refuses it, if any; a space of
    /// more than [`MAX_LISTED_SELECTIONS`] is refused (`TooManySelections`)
    /// rather than built.
    pub fn selections(&self) -> Result<Vec<SelectionVerdict>, Diagnostics> {
        space::listed(self)
    }

    /// The flat launcher of `selection` (a flat launcher: itself).
    pub fn resolve(&self, selection: &Selection) -> Result<Resolved, Diagnostics> {
        flatten::resolve(self, selection)
    }

    /// The checks `repo index --check` holds a composed launcher to: the
    /// default selection is legal, every legal selection composes, every
    /// constraint refuses some selection, every option (and every optional
    /// axis unfilled) is reachable, and at most [`MAX_SELECTIONS`]
    /// selections exist.
    pub fn check(&self) -> CompositionCheck {
        space::check(self)
    }
}

/// Reads the launcher at `path` and composes the selection `with` words
/// give: what `resolve`, `check`, `graph` and `up` all start from.
pub fn resolve_launcher(path: &Path, with: &[String]) -> Result<Resolved, Diagnostics> {
    let composition = Composition::load(path)?;
    let selection = composition.select(with)?;
    composition.resolve(&selection)
}

/// A composed launcher parsed as a plain launcher document: the flat
/// launcher of its default selection (what `validate` and
/// `LauncherDoc::load` see).
pub(crate) fn default_flat(
    file: &Arc<SourceFile>,
    diags: &mut Diagnostics,
    cross_check: bool,
) -> Option<LauncherDoc> {
    let result = parse::parse_composition(file).and_then(|c| {
        let selection = c.select(&[])?;
        c.resolve(&selection)
    });
    match result {
        Ok(resolved) => {
            diags.extend(resolved.warnings);
            if cross_check {
                diags.extend(crate::launcher::stack_rules(&resolved.launcher));
            }
            Some(resolved.launcher)
        }
        Err(e) => {
            diags.extend(e);
            None
        }
    }
}
