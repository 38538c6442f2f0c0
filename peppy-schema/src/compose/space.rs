//! The selection space of a composed launcher: every selection its axes
//! allow, which constraint refuses each, and the checks `repo index
//! --check` holds a composed launcher to.

use super::select::{first_violated, violation};
use super::{Choice, ChoiceSource, Composition, MAX_LISTED_SELECTIONS, MAX_SELECTIONS, Selection};
use crate::diag::{Code, Diagnostics};

/// One selection of the space, and whether the constraints allow it.
#[derive(Debug, Clone)]
pub struct SelectionVerdict {
    /// The selection (every filled axis explicit).
    pub selection: Selection,
    /// The index of the first constraint refusing it, and its reason.
    pub refused_by: Option<(usize, String)>,
}

/// What [`Composition::check`] found.
#[derive(Debug, Clone, Default)]
pub struct CompositionCheck {
    /// How many selections the axes allow.
    pub selections: usize,
    /// How many of them the constraints refuse.
    pub refused: usize,
    /// Problems, located in the launcher.
    pub problems: Diagnostics,
}

/// How many selections the axes allow (saturating).
fn count(c: &Composition) -> usize {
    c.axes
        .iter()
        .map(|a| a.options.len() + usize::from(a.optional))
        .fold(1usize, usize::saturating_mul)
}

pub(super) fn listed(c: &Composition) -> Result<Vec<SelectionVerdict>, Diagnostics> {
    let n = count(c);
    if n > MAX_LISTED_SELECTIONS {
        return Err(c
            .components_loc
            .error(
                Code::TooManySelections,
                format!("`components` allow {n} selections, more than the {MAX_LISTED_SELECTIONS} listed"),
            )
            .with_help("select with `--with` instead")
            .into());
    }
    Ok(enumerate(c))
}

fn enumerate(c: &Composition) -> Vec<SelectionVerdict> {
    if c.flat.is_some() {
        return vec![SelectionVerdict {
            selection: Selection::default(),
            refused_by: None,
        }];
    }
    let mut all: Vec<Vec<Choice>> = vec![Vec::new()];
    for a in &c.axes {
        let states: Vec<Option<&str>> = a
            .optional
            .then_some(None)
            .into_iter()
            .chain(a.options.iter().map(|o| Some(o.name.as_str())))
            .collect();
        all = all
            .into_iter()
            .flat_map(|prefix| {
                states.iter().map(move |s| {
                    let mut next = prefix.clone();
                    next.push(Choice {
                        axis: a.name.clone(),
                        option: s.map(str::to_string),
                        source: if s.is_some() {
                            ChoiceSource::Explicit
                        } else {
                            ChoiceSource::Unfilled
                        },
                    });
                    next
                })
            })
            .collect();
    }
    all.into_iter()
        .map(|choices| {
            let selection = Selection { choices };
            let refused_by =
                first_violated(c, &selection).map(|i| (i, c.constraints[i].reason.clone()));
            SelectionVerdict {
                selection,
                refused_by,
            }
        })
        .collect()
}

pub(super) fn check(c: &Composition) -> CompositionCheck {
    let mut out = CompositionCheck::default();
    if c.flat.is_some() {
        out.selections = 1;
        return out;
    }
    out.selections = count(c);
    // The default selection, when there is one, must be legal.
    if let Err(e) = c.select(&[]) {
        for d in e.iter().filter(|d| {
            matches!(
                d.code,
                Code::ConstraintForbidden | Code::ConstraintUnsatisfied
            )
        }) {
            let mut d = d.clone();
            d.code = Code::DefaultSelectionRefused;
            d.message = format!("the default selection is refused: {}", d.message);
            out.problems.push(d);
        }
    }
    if out.selections > MAX_SELECTIONS {
        out.problems.push(
            c.components_loc
                .error(
                    Code::TooManySelections,
                    format!("`components` allow {} selections, more than the {MAX_SELECTIONS} checked one by one", out.selections),
                )
                .with_help("the selections were not composed and checked; split the launcher or constrain fewer axes"),
        );
        return out;
    }
    let verdicts = enumerate(c);
    out.refused = verdicts.iter().filter(|v| v.refused_by.is_some()).count();
    for v in verdicts.iter().filter(|v| v.refused_by.is_none()) {
        if let Err(e) = c.resolve(&v.selection) {
            out.problems.extend(e);
        }
    }
    // Every constraint refuses some selection it is the first to refuse.
    for (i, k) in c.constraints.iter().enumerate() {
        if verdicts
            .iter()
            .any(|v| v.refused_by.as_ref().is_some_and(|(j, _)| *j == i))
        {
            continue;
        }
        let shadow = verdicts
            .iter()
            .filter(|v| violation(k, &v.selection).is_some())
            .find_map(|v| v.refused_by.as_ref().map(|(j, _)| *j));
        let help = match shadow {
            Some(j) => {
                let at = c.constraints[j]
                    .loc
                    .file
                    .line_col(c.constraints[j].loc.span.start);
                format!(
                    "every selection it would refuse is already refused by the constraint at line {}",
                    at.line
                )
            }
            None => "no selection of the axes violates it; remove it or fix its maps".to_string(),
        };
        out.problems.push(
            k.loc
                .error(
                    Code::ConstraintRefusesNothing,
                    "constraint refuses no selection",
                )
                .with_help(help),
        );
    }
    // Every option, and every optional axis left unfilled, is reachable.
    let legal: Vec<&Selection> = verdicts
        .iter()
        .filter(|v| v.refused_by.is_none())
        .map(|v| &v.selection)
        .collect();
    for a in &c.axes {
        for o in &a.options {
            if !legal
                .iter()
                .any(|s| s.option_of(&a.name) == Some(o.name.as_str()))
            {
                out.problems.push(
                    o.loc
                        .error(Code::OptionUnreachable, format!("option `{}={}` is in no selection the constraints allow", a.name, o.name))
                        .with_help("the constraints refuse every selection with it; relax them or remove the option"),
                );
            }
        }
        if a.optional && !legal.iter().any(|s| s.option_of(&a.name).is_none()) {
            out.problems.push(
                a.loc
                    .error(Code::OptionUnreachable, format!("optional axis `{}` cannot be left unfilled: the constraints refuse every such selection", a.name))
                    .with_help("make the axis required (give it a default), or relax the constraints"),
            );
        }
    }
    out
}
