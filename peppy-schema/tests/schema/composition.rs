//! Composed launchers (current_peppyos.md §5.5-§5.12): `components` and
//! `--with`, fragments, adjustments, constraints, the flat launcher and
//! its report, the selection space and the checks of `repo index --check`.

use std::path::Path;

use peppy_schema::{
    ChoiceSource, Code, Composition, Diagnostic, Diagnostics, LauncherDoc, resolve_launcher,
    stack_rules,
};
use proptest::prelude::*;

use crate::support::*;

/// The worked example of the launch-files guide, shaped as peppy reads it.
const MAPPING: &str = r#"{
  peppy_schema: "launcher/v1",
  components: [
    { name: "sensor", provides: ["front_lidar"], default: "hw",
      options: {
        hw: { deployments: [{ source: { name: "lidar_driver:v1" },
                              instances: [{ instance_id: "front_lidar",
                                            arguments: { port: "/dev/ttyUSB0" } }] }] },
        sim: "fragments/sim_lidar.json5",
      } },
    { name: "logging", optional: true, provides: ["log_inst"],
      options: { on: "fragments/logger.json5" } },
  ],
  adjustments: [
    { target: "mapper_inst", when: { sensor: "sim" }, set_arguments: { max_range_m: 30 } },
  ],
  deployments: [
    { source: { name: "mapper", tag: "v1" },
      instances: [{ instance_id: "mapper_inst", arguments: { max_range_m: 12 },
                    links: { scans: ["front_lidar"],
                             log: { vacant: "logging axis is off" } } }] },
  ],
}"#;

const SIM_LIDAR: &str = r#"{ peppy_schema: "launcher_fragment/v1",
  deployments: [{ source: { name: "lidar_sim", tag: "v1" },
                  instances: [{ instance_id: "front_lidar", arguments: { world: "depot" } },
                              { instance_id: "rear_lidar", arguments: { world: "depot" } }] }],
  adjustments: [{ target: "mapper_inst", add_links: { scans: ["rear_lidar"] } }] }"#;

const LOGGER: &str = r#"{ peppy_schema: "launcher_fragment/v1",
  deployments: [{ source: { name: "logger:v1" }, instances: [{ instance_id: "log_inst" }] }],
  adjustments: [{ target: "mapper_inst", set_links: { log: "log_inst" } }] }"#;

fn mapping(tree: &Tree, launcher: &str) -> std::path::PathBuf {
    tree.write("fragments/sim_lidar.json5", SIM_LIDAR);
    tree.write("fragments/logger.json5", LOGGER);
    tree.write("mapping.json5", launcher)
}

fn words(w: &[&str]) -> Vec<String> {
    w.iter().map(|s| s.to_string()).collect()
}

fn resolve_err(path: &Path, with: &[&str]) -> Diagnostics {
    match resolve_launcher(path, &words(with)) {
        Ok(r) => panic!("expected errors, got:\n{}", r.text),
        Err(e) => e,
    }
}

/// `(line, column)` of the first `needle` in `text`.
#[track_caller]
fn at(d: &Diagnostic, text: &str, needle: &str) {
    assert_eq!(lc(d), pos(text, needle), "{d} should point at `{needle}`");
}

#[test]
fn the_worked_example_composes_with_its_report() {
    let tree = Tree::new();
    let path = mapping(&tree, MAPPING);
    let r = resolve_launcher(&path, &words(&["sim,logging=on"])).expect("resolves");
    assert_eq!(
        r.report.lines(),
        [
            "components: sensor=sim  logging=on",
            "adjustments applied:",
            "  mapper_inst.links.scans: + rear_lidar  (fragments/sim_lidar.json5)",
            "  mapper_inst.links.log: {\"vacant\":\"logging axis is off\"} -> \"log_inst\"  (fragments/logger.json5)",
            "  mapper_inst.arguments.max_range_m: 12 -> 30  (mapping.json5 (base))",
            "constraints checked: 0 hold",
        ]
    );
    let ids: Vec<&str> = r
        .launcher
        .instances()
        .map(|(_, i)| i.instance_id.as_str())
        .collect();
    assert_eq!(
        ids,
        ["mapper_inst", "front_lidar", "rear_lidar", "log_inst"]
    );
    assert!(stack_rules(&r.launcher).is_empty());
    let mapper = &r.launcher.deployments[0].instances[0];
    let scans: Vec<String> = mapper.links[1]
        .value
        .targets()
        .iter()
        .map(|t| t.to_string())
        .collect();
    assert_eq!(
        (mapper.links[1].key.as_str(), scans),
        (
            "scans",
            vec!["front_lidar".to_string(), "rear_lidar".to_string()]
        )
    );
    assert!(r.text.contains("max_range_m: 30"), "{}", r.text);

    // The printed flat launcher is a flat launcher, and resolves to itself.
    let flat = tree.write("flat.json5", &r.text);
    let again = resolve_launcher(&flat, &[]).expect("the flat text resolves");
    assert_eq!(again.text, r.text);
    assert!(again.report.selection.is_none());
    LauncherDoc::parse("flat.json5", r.text.clone()).expect("parses as a flat launcher");
    // A flat launcher takes no `--with`.
    let e = resolve_err(&flat, &["sim"]);
    assert_eq!(codes(&e), [Code::WithOnFlatLauncher], "{e}");
}

#[test]
fn the_default_selection_echoes_defaults_and_skips_guarded_adjustments() {
    let tree = Tree::new();
    let path = mapping(&tree, MAPPING);
    let r = resolve_launcher(&path, &[]).expect("resolves");
    let selection = r.report.selection.clone().expect("composed");
    assert_eq!(selection.to_string(), "sensor=hw (default)  logging=(off)");
    assert_eq!(selection.choices[0].source, ChoiceSource::Default);
    assert_eq!(selection.with_words(), "sensor=hw");
    assert_eq!(
        r.report.lines()[1..3],
        [
            "adjustments skipped:".to_string(),
            "  mapper_inst: guard sensor=sim is not met  (mapping.json5 (base))".to_string()
        ]
    );
    // Parsed as a plain launcher document, a composed one is its default selection.
    let (doc, _) = LauncherDoc::load(&path).expect("default selection");
    assert_eq!(doc.deployments.len(), 2);
}

#[test]
fn with_words_are_checked_and_located_at_components() {
    let tree = Tree::new();
    let path = mapping(&tree, MAPPING);
    let cases: &[(&[&str], Code, &str)] = &[
        (&["simm"], Code::UnknownSelection, "did you mean `sim`?"),
        (
            &["sensr=sim"],
            Code::UnknownSelection,
            "did you mean `sensor`?",
        ),
        (
            &["sensor=hww"],
            Code::UnknownSelection,
            "did you mean `sensor=hw`?",
        ),
        (
            &["sim", "sensor=hw"],
            Code::ConflictingSelection,
            "one option",
        ),
        (
            &["sim,,on"],
            Code::UnknownSelection,
            "choices: sensor: hw, sim; logging (optional): on",
        ),
    ];
    for (with, code, help_has) in cases {
        let e = resolve_err(&path, with);
        let d = one(&e, *code);
        at(d, MAPPING, "components");
        assert!(help(d).contains(help_has), "{with:?}: {d}");
    }
    // Repeating one choice is fine.
    resolve_launcher(&path, &words(&["sim", "sensor=sim"])).expect("same choice twice");

    // An option two axes have, bare, is ambiguous; a required axis
    // without a default must be chosen.
    let text = r#"{ peppy_schema: "launcher/v1",
  components: [
    { name: "a", options: { x: { deployments: [{ source: { name: "n:v1" }, instances: [{ instance_id: "i1" }] }] } } },
    { name: "b", default: "x", options: { x: { deployments: [{ source: { name: "m:v1" }, instances: [{ instance_id: "i2" }] }] } } },
  ] }"#;
    let p = tree.write("two.json5", text);
    let e = resolve_err(&p, &["x"]);
    assert_eq!(codes(&e), [Code::AmbiguousSelection], "{e}");
    assert!(help(one(&e, Code::AmbiguousSelection)).contains("`a=x` or `b=x`"));
    let e = resolve_err(&p, &[]);
    let d = one(&e, Code::UnresolvedAxis);
    at(d, text, "\"a\"");
    resolve_launcher(&p, &words(&["a=x"])).expect("chosen");
}

const CONSTRAINED: &str = r#"{ peppy_schema: "launcher/v1",
  components: [
    { name: "robot", default: "real", options: {
        real: { deployments: [{ source: { name: "arm:v1" }, instances: [{ instance_id: "arm" }] }] },
        sim: { deployments: [{ source: { name: "sim:v1" }, instances: [{ instance_id: "arm" }] }] } } },
    { name: "cameras", optional: true, options: {
        usb: { deployments: [{ source: { name: "cam:v1" }, instances: [{ instance_id: "cam" }] }] } } },
  ],
  constraints: [
    { when: { cameras: "usb" }, requires: [{ robot: "real" }], reason: "the cameras film the real rig" },
    { forbids: [{ robot: "sim", cameras: "usb" }], reason: "never both" },
  ],
  deployments: [{ source: { name: "base:v1" }, instances: [{ instance_id: "b" }] }],
}"#;

#[test]
fn constraints_refuse_with_their_reason_where_they_are_written() {
    let tree = Tree::new();
    let p = tree.write("c.json5", CONSTRAINED);
    let e = resolve_err(&p, &["sim,usb"]);
    let d = one(&e, Code::ConstraintUnsatisfied);
    at(d, CONSTRAINED, "{ when: { cameras: \"usb\" }");
    assert_eq!(
        d.message,
        "selecting cameras=usb requires robot=real, which this selection (robot=sim  cameras=usb) does not satisfy: the cameras film the real rig"
    );
    let c = Composition::load(&p).expect("loads");
    let verdicts = c.selections().expect("few");
    let listed: Vec<(String, Option<usize>)> = verdicts
        .iter()
        .map(|v| {
            (
                v.selection.with_words(),
                v.refused_by.as_ref().map(|(i, _)| *i),
            )
        })
        .collect();
    assert_eq!(
        listed,
        [
            ("robot=real".to_string(), None),
            ("robot=real,cameras=usb".to_string(), None),
            ("robot=sim".to_string(), None),
            ("robot=sim,cameras=usb".to_string(), Some(0)),
        ]
    );
    // The second constraint refuses only what the first already does.
    let found = c.check();
    assert_eq!((found.selections, found.refused), (4, 1));
    let d = one(&found.problems, Code::ConstraintRefusesNothing);
    at(d, CONSTRAINED, "{ forbids:");
    assert!(help(d).contains("line 10"), "{}", help(d));

    // Forbidden, preferred when a forbids entry matches.
    let text = CONSTRAINED.replace(
        "{ when: { cameras: \"usb\" }, requires: [{ robot: \"real\" }], reason: \"the cameras film the real rig\" },\n",
        "",
    );
    let p = tree.write("f.json5", &text);
    let e = resolve_err(&p, &["robot=sim,cameras=usb"]);
    assert_eq!(
        one(&e, Code::ConstraintForbidden).message,
        "this launcher forbids robot=sim and cameras=usb, which this selection (robot=sim  cameras=usb) has: never both"
    );
    assert!(
        Composition::load(&p)
            .expect("loads")
            .check()
            .problems
            .is_empty()
    );
}

#[test]
fn index_checks_find_unreachable_options_and_a_refused_default() {
    let tree = Tree::new();
    let text = CONSTRAINED.replace("reason: \"never both\"", "reason: \"never both\" },\n    { forbids: [{ robot: \"real\" }], reason: \"no real robot today\"");
    let p = tree.write("u.json5", &text);
    let found = Composition::load(&p).expect("loads").check();
    let d = one(&found.problems, Code::DefaultSelectionRefused);
    assert!(d.message.contains("no real robot today"), "{d}");
    let unreachable: Vec<&str> = all(&found.problems, Code::OptionUnreachable)
        .iter()
        .map(|d| d.message.as_str())
        .collect();
    assert_eq!(
        unreachable,
        [
            "option `robot=real` is in no selection the constraints allow",
            "option `cameras=usb` is in no selection the constraints allow"
        ]
    );

    // Ten axes of two options: 1024 selections, over the ceiling.
    let axes: Vec<String> = (0..10)
        .map(|i| {
            format!(
                "{{ name: \"a{i}\", default: \"x{i}\", options: {{ x{i}: {{}}, y{i}: {{}} }} }}"
            )
        })
        .collect();
    let text = format!(
        "{{ peppy_schema: \"launcher/v1\", components: [{}], deployments: [{{ source: {{ name: \"n:v1\" }}, instances: [{{ instance_id: \"i\" }}] }}] }}",
        axes.join(",")
    );
    let p = tree.write("big.json5", &text);
    let found = Composition::load(&p).expect("loads").check();
    assert_eq!(found.selections, 1024);
    assert_eq!(codes(&found.problems), [Code::TooManySelections]);

    // Seventeen: 131072 selections, more than are ever listed.
    let axes: Vec<String> = (0..17)
        .map(|i| {
            format!(
                "{{ name: \"a{i}\", default: \"x{i}\", options: {{ x{i}: {{}}, y{i}: {{}} }} }}"
            )
        })
        .collect();
    let text = text.replacen(
        &text[text.find('[').unwrap()..text.find("], deployments").unwrap() + 1],
        &format!("[{}]", axes.join(",")),
        1,
    );
    let p = tree.write("huge.json5", &text);
    let c = Composition::load(&p).expect("loads");
    let e = c.selections().expect_err("too many to list");
    assert_eq!(codes(&e), [Code::TooManySelections]);
    assert_eq!(c.check().selections, 131_072);
}

#[test]
fn fragment_paths_files_and_contents_are_checked() {
    let tree = Tree::new();
    tree.write("frag/ok.json5", r#"{ peppy_schema: "launcher_fragment/v1", deployments: [{ source: { name: "n:v1" }, instances: [{ instance_id: "i" }] }] }"#);
    tree.write(
        "frag/node.json5",
        r#"{ peppy_schema: "launcher/v1", deployments: [] }"#,
    );
    let bad_inside = r#"{ peppy_schema: "launcher_fragment/v1",
  deployments: [{ source: { name: "n:v1" }, instances: [{ instance_id: "i", bogus: 1 }] }] }"#;
    tree.write("frag/bad.json5", bad_inside);
    let cases = [
        ("../outside.json5", Code::FragmentPath),
        ("/etc/passwd", Code::FragmentPath),
        ("frag/./ok.json5", Code::FragmentPath),
        ("frag/missing.json5", Code::FragmentUnreadable),
        ("frag/node.json5", Code::FragmentInvalid),
    ];
    for (frag, code) in cases {
        let text = format!(
            "{{ peppy_schema: \"launcher/v1\",\n  components: [{{ name: \"a\", default: \"x\", options: {{ x: \"frag/ok.json5\", y: \"{frag}\" }} }}] }}"
        );
        let p = tree.write("l.json5", &text);
        let e = Composition::load(&p).expect_err(frag);
        let d = one(&e, code);
        at(d, &text, &format!("\"{frag}\""));
        assert_eq!(key(d), "components[0].options.y", "{d}");
    }
    // An error inside a fragment is located in the fragment.
    let text = "{ peppy_schema: \"launcher/v1\", components: [{ name: \"a\", default: \"x\", options: { x: \"frag/bad.json5\" } }] }";
    let p = tree.write("l.json5", text);
    let e = Composition::load(&p).expect_err("bad fragment");
    let d = one(&e, Code::UnknownKey);
    assert!(
        d.file_path().expect("located").ends_with("frag/bad.json5"),
        "{d}"
    );
    at(d, bad_inside, "bogus");
    // One file shared by two options is read once; both options compose.
    let text = "{ peppy_schema: \"launcher/v1\", components: [{ name: \"a\", default: \"x\", options: { x: \"frag/ok.json5\", y: [\"frag/ok.json5\"] } }] }";
    let p = tree.write("l.json5", text);
    assert!(
        Composition::load(&p)
            .expect("loads")
            .check()
            .problems
            .is_empty()
    );
}

#[cfg(unix)]
#[test]
fn a_symlink_may_not_lead_a_fragment_outside() {
    let tree = Tree::new();
    let outside = Tree::new();
    let target = outside.write("f.json5", r#"{ peppy_schema: "launcher_fragment/v1" }"#);
    tree.mkdir("frag");
    std::os::unix::fs::symlink(&target, tree.path("frag/link.json5")).expect("symlink");
    let text = "{ peppy_schema: \"launcher/v1\", components: [{ name: \"a\", default: \"x\", options: { x: \"frag/link.json5\" } }] }";
    let p = tree.write("l.json5", text);
    let e = Composition::load(&p).expect_err("escapes");
    at(one(&e, Code::FragmentPath), text, "\"frag/link.json5\"");
}

/// A launcher with two fragment files selected together, and `extra`
/// spliced into the base.
fn adjusted(
    tree: &Tree,
    one_adj: &str,
    two_adj: &str,
    extra: &str,
) -> (std::path::PathBuf, String) {
    tree.write(
        "one.json5",
        &format!(
            r#"{{ peppy_schema: "launcher_fragment/v1",
  deployments: [{{ source: {{ name: "a:v1" }}, instances: [{{ instance_id: "a1" }}] }}],
  adjustments: [{one_adj}] }}"#
        ),
    );
    tree.write(
        "two.json5",
        &format!(
            r#"{{ peppy_schema: "launcher_fragment/v1",
  deployments: [{{ source: {{ name: "b:v1" }}, instances: [{{ instance_id: "b1" }}] }}],
  adjustments: [{two_adj}] }}"#
        ),
    );
    let text = format!(
        r#"{{ peppy_schema: "launcher/v1",
  components: [
    {{ name: "p", default: "one", provides: ["a1"], options: {{ one: "one.json5" }} }},
    {{ name: "q", default: "two", options: {{ two: "two.json5" }} }},
  ],
  {extra}
  deployments: [{{ source: {{ name: "base:v1" }}, instances: [{{ instance_id: "hub", arguments: {{ rate: 1 }}, links: {{ solo: "a1", vac: {{ vacant: "none" }}, many: ["a1"] }} }}] }}],
}}"#
    );
    (tree.write("adj.json5", &text), text)
}

#[test]
fn adjustments_conflict_target_nothing_or_break_links_with_located_errors() {
    let tree = Tree::new();
    // Two fragments writing one argument.
    let (p, _) = adjusted(
        &tree,
        r#"{ target: "hub", set_arguments: { rate: 2 } }"#,
        r#"{ target: "hub", set_arguments: { rate: 3 } }"#,
        "",
    );
    let e = resolve_err(&p, &[]);
    let d = one(&e, Code::AdjustmentsConflict);
    assert!(
        d.file_path().expect("located").ends_with("two.json5"),
        "{d}"
    );
    assert_eq!(
        d.message,
        "one.json5 and two.json5 both write `hub.arguments.rate`"
    );
    // The base overrides fragments without conflict.
    let (p, _) = adjusted(
        &tree,
        r#"{ target: "hub", set_arguments: { rate: 2 } }"#,
        "",
        r#"adjustments: [{ target: "hub", set_arguments: { rate: 4 } }],"#,
    );
    let r = resolve_launcher(&p, &[]).expect("base wins");
    assert!(
        r.report
            .lines()
            .contains(&"  hub.arguments.rate: 2 -> 4  (adj.json5 (base))".to_string()),
        "{:?}",
        r.report.lines()
    );
    // One fragment appending to a slot it also replaces.
    let (p, _) = adjusted(
        &tree,
        r#"{ target: "hub", add_links: { many: ["b1"] } }, { target: "hub", unset_links: ["many"] }"#,
        "",
        "",
    );
    assert_eq!(codes(&resolve_err(&p, &[])), [Code::AdjustmentsConflict]);
    // Appending to a single target or a vacancy, or a target twice.
    for (slot, code) in [
        ("solo", Code::AddLinksOnNonArray),
        ("vac", Code::AddLinksOnNonArray),
        ("many", Code::AddLinksDuplicateTarget),
    ] {
        let (p, _) = adjusted(
            &tree,
            &format!(r#"{{ target: "hub", add_links: {{ {slot}: ["a1"] }} }}"#),
            "",
            "",
        );
        let e = resolve_err(&p, &[]);
        let d = one(&e, code);
        assert!(
            d.file_path().expect("located").ends_with("one.json5"),
            "{d}"
        );
    }
    // A target nobody defines, with a did-you-mean, at the adjustment.
    let (p, text) = adjusted(
        &tree,
        "",
        "",
        r#"adjustments: [{ target: "hubb", set_arguments: { rate: 4 } }],"#,
    );
    let e = Composition::load(&p).expect_err("dead target");
    let d = one(&e, Code::TargetDefinedNowhere);
    at(d, &text, "{ target: \"hubb\"");
    assert!(help(d).starts_with("did you mean `hub`?"), "{d}");
    // A guard naming an axis that does not exist.
    let (p, text) = adjusted(
        &tree,
        "",
        "",
        r#"adjustments: [{ target: "hub", when: { pp: "one" }, set_arguments: { rate: 4 } }],"#,
    );
    let e = Composition::load(&p).expect_err("unknown axis");
    let d = one(&e, Code::UnknownSelection);
    at(d, &text, "pp: \"one\"");
    assert!(help(d).starts_with("did you mean `p`?"), "{d}");
    // An option that does not define what its axis provides.
    let (p, _) = adjusted(&tree, "", "", "");
    let text = std::fs::read_to_string(&p)
        .expect("read")
        .replace("provides: [\"a1\"]", "provides: [\"a1\", \"a2\"]");
    let p = tree.write("adj.json5", &text);
    let e = Composition::load(&p).expect_err("provides");
    at(one(&e, Code::ProvidesUnmet), &text, "one: \"one.json5\"");
    // Two origins defining one instance.
    let text = text
        .replace("provides: [\"a1\", \"a2\"]", "provides: []")
        .replace("instance_id: \"hub\"", "instance_id: \"b1\"")
        .replace(
            "links: { solo: \"a1\", vac: { vacant: \"none\" }, many: [\"a1\"] }",
            "",
        );
    let p = tree.write("adj.json5", &text);
    let e = resolve_err(&p, &[]);
    let d = one(&e, Code::DuplicateInstanceId);
    assert_eq!(
        d.message,
        "instance `b1` is defined by both adj.json5 (base) and two.json5"
    );
}

/// A generated composed launcher: axes of options (inline fragments),
/// optional axes, guarded adjustments and constraints naming whatever
/// the generator picked, links to instances that may not exist.
fn generated() -> impl Strategy<Value = String> {
    let axis = (1usize..4, any::<bool>(), 0usize..3);
    (
        prop::collection::vec(axis, 1..4),
        prop::collection::vec((0usize..4, 0usize..4, 0usize..6, any::<bool>()), 0..4),
        prop::collection::vec((0usize..4, 0usize..4, 0usize..4, 0usize..4, any::<bool>()), 0..3),
    )
        .prop_map(|(axes, adjustments, constraints)| {
            let name = |a: usize| format!("ax{a}");
            let opt = |a: usize, o: usize| format!("o{a}_{o}");
            let mut comps = Vec::new();
            for (a, (n, optional, link)) in axes.iter().enumerate() {
                let options: Vec<String> = (0..*n)
                    .map(|o| format!(
                        "{}: {{ deployments: [{{ source: {{ name: \"n{a}:v1\" }}, instances: [{{ instance_id: \"i{a}_{o}\", links: {{ up: \"i{link}_0\" }} }}] }}] }}",
                        opt(a, o)
                    ))
                    .collect();
                let default = if *optional { "optional: true".to_string() } else { format!("default: \"{}\"", opt(a, 0)) };
                comps.push(format!("{{ name: \"{}\", {default}, options: {{ {} }} }}", name(a), options.join(", ")));
            }
            let pick = |a: usize, o: usize| {
                let a = a % axes.len();
                (name(a), opt(a, o % axes[a].0))
            };
            let adj: Vec<String> = adjustments
                .iter()
                .map(|(a, o, t, guard)| {
                    let (ax, op) = pick(*a, *o);
                    let target = format!("i{}_{}", t % axes.len(), t % 2);
                    let target = if target == "i0_1" && axes[0].0 < 2 { "base_i".to_string() } else { target };
                    let target = if axes[t % axes.len()].0 <= t % 2 { "base_i".to_string() } else { target };
                    let when = if *guard { format!("when: {{ {ax}: \"{op}\" }}, ") } else { String::new() };
                    format!("{{ target: \"{target}\", {when}set_arguments: {{ k: {t} }}, add_links: {{ extra: [\"base_i\"] }} }}")
                })
                .collect();
            let cons: Vec<String> = constraints
                .iter()
                .map(|(a, o, b, p, forbid)| {
                    let (ax, op) = pick(*a, *o);
                    let (bx, bp) = pick(*b, *p);
                    let body = if bx == ax { format!("{{ {bx}: \"{bp}\" }}") } else { format!("{{ {ax}: \"{op}\", {bx}: \"{bp}\" }}") };
                    if *forbid { format!("{{ forbids: [{body}], reason: \"r\" }}") } else { format!("{{ requires: [{body}], reason: \"r\" }}") }
                })
                .collect();
            format!(
                "{{ peppy_schema: \"launcher/v1\", components: [{}], adjustments: [{}], constraints: [{}],\n  deployments: [{{ source: {{ name: \"base:v1\" }}, instances: [{{ instance_id: \"base_i\" }}] }}] }}",
                comps.join(", "),
                adj.join(", "),
                cons.join(", ")
            )
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, .. ProptestConfig::default() })]

    /// Resolving any selection gives a flat launcher the launcher checker
    /// accepts (and that resolves to itself), or located errors; never a
    /// panic.
    #[test]
    fn every_selection_resolves_or_fails_located(text in generated()) {
        let tree = Tree::new();
        let p = tree.write("gen.json5", &text);
        let located = |e: &Diagnostics| e.iter().all(|d| d.file_path().is_some() && d.span().is_some());
        match Composition::load(&p) {
            Err(e) => prop_assert!(located(&e), "{e}"),
            Ok(c) => {
                let _ = c.check();
                for v in c.selections().expect("few") {
                    match c.resolve(&v.selection) {
                        Err(e) => prop_assert!(v.refused_by.is_some() || located(&e), "{e}"),
                        Ok(r) => {
                            let rules = stack_rules(&r.launcher);
                            prop_assert!(located(&rules), "{rules}");
                            let flat = tree.write("flat.json5", &r.text);
                            let again = resolve_launcher(&flat, &[]);
                            match again {
                                Ok(again) => prop_assert_eq!(again.text, r.text),
                                Err(e) => prop_assert!(located(&e), "{e}"),
                            }
                        }
                    }
                }
            }
        }
    }
}

/// A composed launcher names core nodes and link keys by the rules a flat
/// `launcher/v1` file follows (one rule each, in `peppy_schema::names`).
#[test]
fn composed_launchers_follow_the_flat_core_node_and_link_key_rules() {
    let tree = Tree::new();
    let text = MAPPING.replace(
        r#"peppy_schema: "launcher/v1","#,
        r#"peppy_schema: "launcher/v1", core_nodes: ["self"],"#,
    );
    let path = mapping(&tree, &text);
    let errors = resolve_err(&path, &[]);
    let d = errors
        .iter()
        .find(|d| d.code == Code::InvalidName)
        .unwrap_or_else(|| panic!("{errors}"));
    assert!(d.message.contains("`self` stands for"), "{d}");
    at(d, &text, r#""self""#);

    let text = MAPPING.replace(
        "set_arguments: { max_range_m: 30 }",
        "set_links: { _: \"front_lidar\" }",
    );
    let path = mapping(&tree, &text);
    let errors = resolve_err(&path, &["sensor=sim"]);
    let d = errors
        .iter()
        .find(|d| d.code == Code::LinkSentinelKey)
        .unwrap_or_else(|| panic!("{errors}"));
    assert_eq!(d.message, "link key `_` is reserved");
}
