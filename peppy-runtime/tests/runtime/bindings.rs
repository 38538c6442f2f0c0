//! One binding engine: a node started on its own with `--bind` (or
//! the slashed spelling's `--link` / `--vacant-link`) flags (as
//! `peppy-launch run` and `peppy-launch plan` start it) gets exactly the
//! plan `up` gives it from the launcher file (slots, filters, parameters),
//! for every example launcher.

use std::path::{Path, PathBuf};

use peppy_schema::{LinkValue, NodeModel, RepoOptions, check_launcher};

fn examples() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples")
}

#[test]
fn run_bind_and_up_bind_every_example_launcher_identically() {
    let dir = tempfile::tempdir().unwrap();
    let mut launchers: Vec<PathBuf> = std::fs::read_dir(examples().join("launchers"))
        .unwrap()
        .map(|e| e.unwrap().path())
        // `up` leaves its run directories (`.peppy/`) beside the launchers.
        .filter(|p| p.extension().is_some_and(|e| e == "json5"))
        .collect();
    launchers.sort();
    let options = RepoOptions {
        explicit: vec![examples()],
        env: None,
        last: Vec::new(),
    };
    let mut compared = Vec::new();
    for launcher in &launchers {
        let stack = match check_launcher(launcher, &options) {
            Ok(stack) => stack,
            // The deliberately wrong example is refused by both paths alike
            // (the schema tests cover it).
            Err(_) if launcher.ends_with("wrong_interface.json5") => continue,
            Err(e) => panic!("{}: {e}", launcher.display()),
        };
        for (d, inst) in stack.launcher.instances() {
            let planned = stack.plan.instance(&inst.instance_id).unwrap();
            let doc = NodeModel::of(&stack.deployments[d].resolved.node);
            let params = dir.path().join(format!("{}.json", inst.instance_id));
            std::fs::write(&params, planned.parameters.to_string()).unwrap();
            let mut args = vec![
                "node".to_string(),
                "--instance-id".into(),
                inst.instance_id.clone(),
                "--params".into(),
                params.display().to_string(),
            ];
            // A `launcher_v1` binding is `--bind`; a `launcher/v1` link a flag
            // per target, in order; a vacancy by its reason.
            for l in &inst.links {
                match &l.value {
                    LinkValue::Bound(t) => {
                        args.extend(["--bind".into(), format!("{}@{}", l.key, t.instance)]);
                    }
                    LinkValue::Vacant { reason, .. } => {
                        args.extend(["--vacant-link".into(), format!("{}={reason}", l.key)]);
                    }
                    value => {
                        for t in value.targets() {
                            args.extend(["--link".into(), format!("{}@{}", l.key, t.instance)]);
                        }
                    }
                }
            }
            let from_flags = peppy_runtime::startup_from_flags(&doc, args)
                .unwrap_or_else(|e| panic!("{}: {}: {e}", launcher.display(), inst.instance_id));
            let at = format!("{}: instance `{}`", launcher.display(), inst.instance_id);
            assert_eq!(from_flags.slots, planned.slots, "{at}");
            assert_eq!(from_flags.parameters, planned.parameters, "{at}");
            compared.push(inst.instance_id.clone());
        }
    }
    // Every valid example launcher took part, consumers with free-form keys
    // and `launcher/v1` links (a list and a vacancy) among them.
    assert!(compared.len() >= 12, "{compared:?}");
    assert!(compared.iter().any(|i| i == "mosaic_1"), "{compared:?}");
    assert!(compared.iter().any(|i| i == "viewer"), "{compared:?}");
}
