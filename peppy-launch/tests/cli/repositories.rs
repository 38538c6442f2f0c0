//! Repositories from git: a project's `peppy_repositories.json5` naming a
//! git repository, and the user's list kept by `repo add/list/remove/
//! refresh`. Repositories are local bare repositories (`file://` and
//! plain paths); "the server stopped" is the repository moved away.

use std::path::{Path, PathBuf};

use crate::sources::git;
use crate::support::{Run, peppy_launch_with};

/// A shell node that says its name and ends.
fn shell_node(name: &str) -> String {
    format!(
        r#"{{ peppy_schema: "node_v1", manifest: {{ name: "{name}", tag: "v1" }},
            execution: {{ language: "shell", run_cmd: ["sh", "-c", "echo {name} says hello"] }} }}"#
    )
}

/// A launcher naming nodes by `name:tag` only.
fn launcher(nodes: &[&str]) -> String {
    let deployments: Vec<String> = nodes
        .iter()
        .map(|n| {
            format!(
                r#"{{ source: {{ name: "{n}:v1" }}, instances: [{{ instance_id: "{n}_1", restart: "no" }}] }}"#
            )
        })
        .collect();
    format!(
        "{{ peppy_schema: \"launcher_v1\", deployments: [{}] }}",
        deployments.join(", ")
    )
}

/// A hub: nodes `cam` and `arm` and launcher `hub_stack` running both,
/// committed in a work tree and served as the bare repository `served`.
fn hub(work: &Path, served: &Path) {
    for node in ["cam", "arm"] {
        std::fs::create_dir_all(work.join("nodes").join(node)).unwrap();
        std::fs::write(
            work.join("nodes").join(node).join("peppy.json5"),
            shell_node(node),
        )
        .unwrap();
    }
    std::fs::create_dir_all(work.join("launchers")).unwrap();
    std::fs::write(
        work.join("launchers/hub_stack.json5"),
        launcher(&["cam", "arm"]),
    )
    .unwrap();
    git(work, &["init", "--quiet"]);
    git(work, &["add", "."]);
    git(work, &["commit", "--quiet", "-m", "cam and arm"]);
    git(
        work.parent().unwrap(),
        &[
            "clone",
            "--quiet",
            "--bare",
            work.to_str().unwrap(),
            served.to_str().unwrap(),
        ],
    );
}

/// Commits `nodes/NAME` and a launcher `NAME_stack` running it to the hub,
/// and pushes it to `served`.
fn publish_node(work: &Path, served: &Path, name: &str) {
    std::fs::create_dir_all(work.join("nodes").join(name)).unwrap();
    std::fs::write(
        work.join("nodes").join(name).join("peppy.json5"),
        shell_node(name),
    )
    .unwrap();
    std::fs::write(
        work.join("launchers").join(format!("{name}_stack.json5")),
        launcher(&[name]),
    )
    .unwrap();
    git(work, &["add", "."]);
    git(work, &["commit", "--quiet", "-m", name]);
    git(
        work,
        &["push", "--quiet", served.to_str().unwrap(), "HEAD:main"],
    );
}

struct Machine {
    _tmp: tempfile::TempDir,
    root: PathBuf,
    config: PathBuf,
    cache: PathBuf,
}

impl Machine {
    fn new() -> Machine {
        let tmp = tempfile::tempdir().unwrap();
        let root = tmp.path().to_path_buf();
        let (config, cache) = (root.join("config"), root.join("cache"));
        Machine {
            _tmp: tmp,
            root,
            config,
            cache,
        }
    }

    fn peppy_launch(&self, dir: &Path, args: &[&str]) -> Run {
        peppy_launch_with(
            dir,
            args,
            &[
                ("PEPPY_CONFIG_DIR", &self.config),
                ("PEPPY_CACHE_DIR", &self.cache),
            ],
        )
    }
}

fn ok(run: &Run, what: &str) {
    assert_eq!(run.code, 0, "{what}:\n{}\n{}", run.stdout, run.stderr);
}

/// A project whose `peppy_repositories.json5` names a git repository runs
/// a launcher of that repository by name, its nodes found by `name:tag`,
/// with no folder on the command line; once cached, it runs again with the
/// repository gone.
#[test]
fn a_launch_from_a_git_repository_runs_again_offline() {
    let m = Machine::new();
    let (work, served, project) = (
        m.root.join("hub"),
        m.root.join("served/hub.git"),
        m.root.join("project"),
    );
    std::fs::create_dir_all(&work).unwrap();
    std::fs::create_dir_all(&project).unwrap();
    hub(&work, &served);
    std::fs::write(
        project.join("peppy_repositories.json5"),
        format!(
            "[{{ type: \"git\", url: \"file://{}\", ref: \"main\" }}]",
            served.display()
        ),
    )
    .unwrap();

    let first = m.peppy_launch(&project, &["up", "hub_stack"]);
    ok(&first, "up from the git repository");
    // Instances' output is the launch's stderr, prefixed with their ids.
    for said in ["[cam_1] cam says hello", "[arm_1] arm says hello"] {
        assert!(first.stderr.contains(said), "{}", first.stderr);
    }

    // The repository is gone: the cached copy is used as it is.
    std::fs::rename(&served, m.root.join("served/moved.git")).unwrap();
    let second = m.peppy_launch(&project, &["up", "hub_stack"]);
    ok(&second, "up from the cache");
    assert!(
        second.stderr.contains("cam says hello"),
        "{}",
        second.stderr
    );

    // `check` and a node by name read the same cache.
    ok(&m.peppy_launch(&project, &["check", "hub_stack"]), "check");
    let sync = m.peppy_launch(&project, &["sync", "cam:v1"]);
    ok(&sync, "a node by name");
}

/// The user's list: the public hubs while there is no list (read from the
/// cache only, so nothing reaches the network), `repo add` of a git
/// repository (fetched at once), `repo remove` turning the hubs off,
/// `repo refresh` bringing a new commit, and a refresh that cannot reach
/// the repository keeping the cached commit.
#[test]
fn the_users_list_is_added_to_listed_refreshed_and_trimmed() {
    let m = Machine::new();
    let (work, served, elsewhere) = (
        m.root.join("hub"),
        m.root.join("served/hub.git"),
        m.root.join("elsewhere"),
    );
    std::fs::create_dir_all(&work).unwrap();
    std::fs::create_dir_all(&elsewhere).unwrap();
    hub(&work, &served);

    let defaults = m.peppy_launch(&elsewhere, &["repo", "list"]);
    ok(&defaults, "repo list");
    for hub in [
        "nodes-hub",
        "launchers-hub",
        "openarm-nodes",
        "contracts-hub",
    ] {
        assert!(defaults.stdout.contains(hub), "{}", defaults.stdout);
    }
    assert!(
        defaults.stdout.contains("the default list") && defaults.stdout.contains("not fetched yet"),
        "{}",
        defaults.stdout
    );
    // A name no repository has says which listed ones are not fetched.
    let missing = m.peppy_launch(&elsewhere, &["up", "hub_stack"]);
    assert_eq!(missing.code, 2, "{}", missing.stderr);
    assert!(
        missing.stderr.contains("not fetched yet: nodes-hub"),
        "{}",
        missing.stderr
    );

    let added = m.peppy_launch(&elsewhere, &["repo", "add", served.to_str().unwrap()]);
    ok(&added, "repo add");
    assert!(added.stdout.contains("fetched hub"), "{}", added.stdout);
    let again = m.peppy_launch(&elsewhere, &["repo", "add", served.to_str().unwrap()]);
    assert_eq!(again.code, 2, "{}", again.stderr);
    assert!(again.stderr.contains("already"), "{}", again.stderr);

    let trimmed = m.peppy_launch(
        &elsewhere,
        &[
            "repo",
            "remove",
            "nodes-hub",
            "launchers-hub",
            "openarm-nodes",
            "contracts-hub",
        ],
    );
    ok(&trimmed, "repo remove");
    let listed = m.peppy_launch(&elsewhere, &["repo", "list"]);
    ok(&listed, "repo list");
    assert!(!listed.stdout.contains("nodes-hub"), "{}", listed.stdout);
    assert!(
        listed.stdout.contains("hub (")
            && listed.stdout.contains("2 nodes, 0 contracts, 1 launchers"),
        "{}",
        listed.stdout
    );
    let unknown = m.peppy_launch(&elsewhere, &["repo", "remove", "nodes-hub"]);
    assert_eq!(unknown.code, 2, "{}", unknown.stderr);
    assert!(unknown.stderr.contains("it has: hub"), "{}", unknown.stderr);

    // Any directory: the user's list is searched everywhere.
    ok(&m.peppy_launch(&elsewhere, &["up", "hub_stack"]), "up");

    // A new commit is seen after a refresh, not before.
    publish_node(&work, &served, "lidar");
    let stale = m.peppy_launch(&elsewhere, &["up", "lidar_stack"]);
    assert_eq!(stale.code, 2, "{}", stale.stderr);
    let refreshed = m.peppy_launch(&elsewhere, &["repo", "refresh"]);
    ok(&refreshed, "repo refresh");
    let head = git(&work, &["rev-parse", "HEAD"]);
    assert!(refreshed.stdout.contains(&head), "{}", refreshed.stdout);
    let fresh = m.peppy_launch(&elsewhere, &["up", "lidar_stack"]);
    ok(&fresh, "up after the refresh");
    assert!(
        fresh.stderr.contains("lidar says hello"),
        "{}",
        fresh.stderr
    );

    // Unreachable: the refresh says so and keeps what it had.
    std::fs::rename(&served, m.root.join("served/moved.git")).unwrap();
    let offline = m.peppy_launch(&elsewhere, &["repo", "refresh"]);
    ok(&offline, "repo refresh, offline");
    assert!(
        offline.stdout.contains("cannot reach") && offline.stdout.contains(&head),
        "{}",
        offline.stdout
    );
    ok(
        &m.peppy_launch(&elsewhere, &["up", "lidar_stack"]),
        "up offline",
    );

    // A repository that cannot be fetched is named, and not added.
    let nowhere = m.root.join("served/nowhere.git");
    let refused = m.peppy_launch(&elsewhere, &["repo", "add", nowhere.to_str().unwrap()]);
    assert_ne!(refused.code, 0);
    assert!(
        refused.stderr.contains("cannot fetch") && refused.stderr.contains("nowhere.git"),
        "{}",
        refused.stderr
    );
    let list = std::fs::read_to_string(m.config.join("repositories.json5")).unwrap();
    assert!(!list.contains("nowhere"), "{list}");
}
