//! `--with` words to a selection, and the constraints that judge it.

use super::{Choice, ChoiceSource, Composition, Constraint, Pair, Selection};
use crate::diag::{Code, Diagnostics, did_you_mean, list};

/// The axes and options, for messages: `robot: real, mujoco; recorder: ...`.
fn menu(c: &Composition) -> String {
    c.axes
        .iter()
        .map(|a| {
            format!(
                "{}{}: {}",
                a.name,
                if a.optional { " (optional)" } else { "" },
                a.options
                    .iter()
                    .map(|o| o.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        })
        .collect::<Vec<_>>()
        .join("; ")
}

pub(super) fn select(c: &Composition, words: &[String]) -> Result<Selection, Diagnostics> {
    let mut diags = Diagnostics::new();
    let at = |code: Code, message: String| c.components_loc.error(code, message);
    let words: Vec<&str> = words
        .iter()
        .flat_map(|w| w.split(','))
        .map(str::trim)
        .collect();
    if c.flat.is_some() {
        if words.is_empty() {
            return Ok(Selection::default());
        }
        return Err(at(
            Code::WithOnFlatLauncher,
            format!(
                "`--with {}` was given, but this launcher has no `components`",
                words.join(",")
            ),
        )
        .with_help("a flat launcher is one stack with nothing to select; leave `--with` out")
        .into());
    }
    let mut chosen: Vec<Option<String>> = vec![None; c.axes.len()];
    for word in words {
        if word.is_empty() {
            diags.push(
                at(
                    Code::UnknownSelection,
                    "a `--with` word is empty".to_string(),
                )
                .with_help(format!("choices: {}", menu(c))),
            );
            continue;
        }
        let (axis_i, option) = match word.split_once('=') {
            Some((axis, option)) => {
                let Some(i) = c.axes.iter().position(|a| a.name == axis) else {
                    let names = c.axes.iter().map(|a| a.name.as_str());
                    let help = match did_you_mean(axis, names.clone()) {
                        Some(s) => format!("did you mean `{s}`? axes: {}", list(names)),
                        None => format!("choices: {}", menu(c)),
                    };
                    diags.push(
                        at(
                            Code::UnknownSelection,
                            format!("`--with {word}`: `{axis}` is not an axis of this launcher"),
                        )
                        .with_help(help),
                    );
                    continue;
                };
                let a = &c.axes[i];
                if !a.options.iter().any(|o| o.name == option) {
                    let names = a.options.iter().map(|o| o.name.as_str());
                    let help = match did_you_mean(option, names.clone()) {
                        Some(s) => format!(
                            "did you mean `{axis}={s}`? options of `{axis}`: {}",
                            list(names)
                        ),
                        None => format!("options of `{axis}`: {}", list(names)),
                    };
                    diags.push(
                        at(
                            Code::UnknownSelection,
                            format!(
                                "`--with {word}`: `{option}` is not an option of axis `{axis}`"
                            ),
                        )
                        .with_help(help),
                    );
                    continue;
                }
                (i, option)
            }
            None => {
                let on: Vec<usize> = c
                    .axes
                    .iter()
                    .enumerate()
                    .filter(|(_, a)| a.options.iter().any(|o| o.name == word))
                    .map(|(i, _)| i)
                    .collect();
                match on.as_slice() {
                    [i] => (*i, word),
                    [] => {
                        let all = c
                            .axes
                            .iter()
                            .flat_map(|a| a.options.iter().map(|o| o.name.as_str()));
                        let help = match did_you_mean(word, all) {
                            Some(s) => format!("did you mean `{s}`? choices: {}", menu(c)),
                            None => format!("choices: {}", menu(c)),
                        };
                        diags.push(
                            at(
                                Code::UnknownSelection,
                                format!("`--with {word}` names no option of this launcher"),
                            )
                            .with_help(help),
                        );
                        continue;
                    }
                    several => {
                        let axes: Vec<&str> =
                            several.iter().map(|&i| c.axes[i].name.as_str()).collect();
                        diags.push(
                            at(
                                Code::AmbiguousSelection,
                                format!(
                                    "`--with {word}` is an option of several axes ({})",
                                    list(axes.iter().copied())
                                ),
                            )
                            .with_help(format!(
                                "say which: {}",
                                axes.iter()
                                    .map(|a| format!("`{a}={word}`"))
                                    .collect::<Vec<_>>()
                                    .join(" or ")
                            )),
                        );
                        continue;
                    }
                }
            }
        };
        match &chosen[axis_i] {
            Some(first) if first != option => diags.push(
                at(
                    Code::ConflictingSelection,
                    format!(
                        "axis `{}` is selected twice, as `{first}` and `{option}`",
                        c.axes[axis_i].name
                    ),
                )
                .with_help("an axis takes one option; keep one"),
            ),
            _ => chosen[axis_i] = Some(option.to_string()),
        }
    }
    let mut choices = Vec::new();
    for (a, chosen) in c.axes.iter().zip(chosen) {
        let choice = match (chosen, &a.default) {
            (Some(o), _) => Choice {
                axis: a.name.clone(),
                option: Some(o),
                source: ChoiceSource::Explicit,
            },
            (None, Some(d)) => Choice {
                axis: a.name.clone(),
                option: Some(d.clone()),
                source: ChoiceSource::Default,
            },
            (None, None) if a.optional => Choice {
                axis: a.name.clone(),
                option: None,
                source: ChoiceSource::Unfilled,
            },
            // A word that failed may have meant this axis: say only that.
            (None, None) if diags.has_errors() => continue,
            (None, None) => {
                diags.push(
                    a.loc
                        .error(
                            Code::UnresolvedAxis,
                            format!("axis `{}` has no default and nothing selects it", a.name),
                        )
                        .with_help(format!(
                            "choose one with `--with`: {}",
                            a.options
                                .iter()
                                .map(|o| format!("`{}={}`", a.name, o.name))
                                .collect::<Vec<_>>()
                                .join(", ")
                        )),
                );
                continue;
            }
        };
        choices.push(choice);
    }
    if diags.has_errors() {
        return Err(diags);
    }
    let selection = Selection { choices };
    judge(c, &selection)?;
    Ok(selection)
}

/// `a=o and b=p`.
fn render_map(map: &[Pair]) -> String {
    map.iter()
        .map(|p| format!("{}={}", p.axis, p.option))
        .collect::<Vec<_>>()
        .join(" and ")
}

/// What `selection` makes of `k`: `None` when it holds.
pub(super) fn violation(k: &Constraint, selection: &Selection) -> Option<(Code, String)> {
    if !selection.matches(&k.when) {
        return None;
    }
    let condition = if k.when.is_empty() {
        "this launcher".to_string()
    } else {
        format!("selecting {}", render_map(&k.when))
    };
    if let Some(f) = k.forbids.iter().find(|f| selection.matches(f)) {
        return Some((
            Code::ConstraintForbidden,
            format!(
                "{condition} forbids {}, which this selection ({selection}) has",
                render_map(f)
            ),
        ));
    }
    if !k.requires.is_empty() && !k.requires.iter().any(|q| selection.matches(q)) {
        let alternatives = k
            .requires
            .iter()
            .map(|q| render_map(q))
            .collect::<Vec<_>>()
            .join(" or ");
        return Some((
            Code::ConstraintUnsatisfied,
            format!(
                "{condition} requires {alternatives}, which this selection ({selection}) does not satisfy"
            ),
        ));
    }
    None
}

/// The first constraint `selection` violates, in declaration order.
pub(super) fn first_violated(c: &Composition, selection: &Selection) -> Option<usize> {
    c.constraints
        .iter()
        .position(|k| violation(k, selection).is_some())
}

pub(super) fn judge(c: &Composition, selection: &Selection) -> Result<(), Diagnostics> {
    let Some(i) = first_violated(c, selection) else {
        return Ok(());
    };
    let k = &c.constraints[i];
    let Some((code, message)) = violation(k, selection) else {
        return Ok(());
    };
    Err(Diagnostics::from(
        k.loc
        .error(code, format!("{message}: {}", k.reason.trim()))
        .with_help("the launcher's constraints refuse this selection; choose other options with `--with` (`resolve --list` shows every selection)"),
    ))
}
