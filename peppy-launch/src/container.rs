//! Nodes that declare `execution.container` (an Apptainer definition).
//!
//! With a container runtime on the machine (`apptainer`, or `singularity`
//! under its older name), the definition is built into an image under the
//! cache and the node runs in it. Without one (or with
//! `PEPPY_CONTAINERS=native`), the node runs natively, as its definition
//! would build and run it: the definition's `%post` commands that build
//! the project (after its `cd` into where `%files` puts the node; system
//! set-up such as `apt-get` is not run, only named), then its
//! `%runscript`'s `exec` line, run in the node's directory. A program the
//! image brings and this machine lacks (a simulator at an absolute path, a
//! tool not on `PATH`) is a clear error naming it.

use std::path::{Path, PathBuf};

use peppy_schema::Container;

/// Chooses how container nodes run: `native` or `apptainer` (default:
/// Apptainer when installed, else native).
pub(crate) const CONTAINERS_ENV: &str = "PEPPY_CONTAINERS";

/// How a container node runs here.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Plan {
    /// As a process: the build commands, then the program.
    Native {
        /// Build commands, in order, run in the node's directory.
        build: Vec<Vec<String>>,
        /// The program and its arguments.
        run: Vec<String>,
        /// What the definition sets up that is not done here (`apt-get
        /// install ...`), for the note.
        skipped: Vec<String>,
    },
    /// In its image: built with `apptainer build`, run with `apptainer run`.
    Apptainer {
        /// The container runtime's program.
        runtime: PathBuf,
        /// The image file (under the cache).
        image: PathBuf,
        /// The definition file.
        definition: PathBuf,
    },
}

/// Why a container node cannot run here.
#[derive(Debug, thiserror::Error)]
pub enum ContainerError {
    /// The definition file cannot be read.
    #[error("cannot read its container definition {}: {source}", path.display())]
    Read {
        /// The definition.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The definition has no `%runscript` `exec` line to run natively.
    #[error("its container definition {} has no `%runscript` with an `exec` line to run natively; install Apptainer to run it in its image", path.display())]
    NoRunscript {
        /// The definition.
        path: PathBuf,
    },
    /// The program the image runs is not on this machine.
    #[error(
        "natively it would run `{program}`, which its image ({image}) brings and this machine lacks; install Apptainer to run it in its image"
    )]
    Missing {
        /// The program.
        program: String,
        /// The image the definition starts from.
        image: String,
    },
    /// `PEPPY_CONTAINERS` names no way to run containers.
    #[error("PEPPY_CONTAINERS is `{0}`; use `native` or `apptainer`")]
    BadChoice(String),
    /// The image cannot be put in the cache.
    #[error("cannot put its container image in the cache: {0}")]
    Image(std::io::Error),
    /// `PEPPY_CONTAINERS=apptainer`, and no runtime is installed.
    #[error("PEPPY_CONTAINERS=apptainer, but neither `apptainer` nor `singularity` is on PATH")]
    NoRuntime,
}

/// An Apptainer definition, as far as running it natively needs.
#[derive(Debug, Default, PartialEq, Eq)]
struct Definition {
    /// `From:`.
    image: String,
    /// Where `%files` puts the node's directory (`. /opt/node`).
    project: Option<String>,
    /// `%post`, one command per entry (continuation lines joined).
    post: Vec<String>,
    /// `%runscript`, likewise.
    runscript: Vec<String>,
}

fn parse(text: &str) -> Definition {
    let mut def = Definition::default();
    let mut section = String::new();
    let mut pending = String::new();
    for raw in text.lines() {
        let line = raw.trim();
        if let Some(rest) = line.strip_suffix('\\') {
            pending.push_str(rest.trim_end());
            pending.push(' ');
            continue;
        }
        let line = format!("{pending}{line}");
        pending.clear();
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        if let Some(name) = line.strip_prefix('%') {
            section = name
                .split_whitespace()
                .next()
                .unwrap_or_default()
                .to_string();
            continue;
        }
        match section.as_str() {
            "" => {
                if let Some(image) = line.strip_prefix("From:") {
                    def.image = image.trim().to_string();
                }
            }
            "files" => {
                let mut parts = line.split_whitespace();
                if let (Some("."), Some(dest)) = (parts.next(), parts.next()) {
                    def.project = Some(dest.trim_end_matches('/').to_string());
                }
            }
            "post" => def.post.push(line.to_string()),
            "runscript" => def.runscript.push(line.to_string()),
            _ => {}
        }
    }
    def
}

/// Words of a shell command line: whitespace-separated, quotes removed.
fn words(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut word = String::new();
    let mut quote = None;
    let mut any = false;
    for c in line.chars() {
        match (quote, c) {
            (None, '"' | '\'') => {
                quote = Some(c);
                any = true;
            }
            (Some(q), c) if c == q => quote = None,
            (None, c) if c.is_whitespace() => {
                if any {
                    out.push(std::mem::take(&mut word));
                    any = false;
                }
            }
            (_, c) => {
                word.push(c);
                any = true;
            }
        }
    }
    if any {
        out.push(word);
    }
    out
}

/// The tools that build a project where it is: the `%post` commands run
/// natively. Anything else there sets the image up.
const BUILD_TOOLS: &[&str] = &[
    "cargo", "uv", "pip", "pip3", "npm", "make", "cmake", "maturin",
];

/// How the native build and run of `def` look, in the node's directory.
fn native(def: &Definition, path: &Path) -> Result<Plan, ContainerError> {
    let project = def.project.clone().unwrap_or_default();
    let in_project = |line: &str| {
        let w = words(line);
        w.first().is_some_and(|c| c == "cd")
            && w.get(1).is_some_and(|d| d.trim_end_matches('/') == project)
    };
    let mut build = Vec::new();
    let mut skipped = Vec::new();
    let mut inside = false;
    // `cd /opt/x && cargo build`: each command of a line on its own.
    let commands = def
        .post
        .iter()
        .flat_map(|line| line.split("&&").flat_map(|part| part.split(';')))
        .map(str::trim)
        .filter(|c| !c.is_empty());
    for line in commands {
        if in_project(line) {
            inside = true;
            continue;
        }
        let w = words(line);
        let Some(program) = w.first() else { continue };
        // uv brings the project's Python itself when it syncs: the image's
        // install of one is neither run nor worth naming.
        if program == "uv" && w.get(1).is_some_and(|s| s == "python") {
            continue;
        }
        if inside && BUILD_TOOLS.contains(&program.as_str()) {
            build.push(w);
        } else if !matches!(program.as_str(), "set" | "export" | "cd") {
            skipped.push(line.to_string());
        }
    }
    let exec = def
        .runscript
        .iter()
        .find_map(|line| line.strip_prefix("exec "))
        .ok_or_else(|| ContainerError::NoRunscript {
            path: path.to_path_buf(),
        })?;
    let mut run: Vec<String> = words(exec)
        .into_iter()
        .filter(|w| w != "$@" && w != "$*")
        .collect();
    if run.is_empty() {
        return Err(ContainerError::NoRunscript {
            path: path.to_path_buf(),
        });
    }
    // The image's copy of the node is the node's own directory here, in
    // the program and in its arguments alike.
    if !project.is_empty() {
        for word in &mut run {
            if let Some(rest) = word.strip_prefix(&format!("{project}/")) {
                *word = format!("./{rest}");
            }
        }
    }
    let program = run[0].clone();
    let here = program.starts_with("./")
        || (!program.starts_with('/') && program.contains('/'))
        || crate::python_sync::on_path(&program).is_some()
        || (program.starts_with('/') && Path::new(&program).is_file());
    if !here {
        return Err(ContainerError::Missing {
            program,
            image: def.image.clone(),
        });
    }
    Ok(Plan::Native {
        build,
        run,
        skipped,
    })
}

/// The container runtime on this machine, if any.
fn runtime() -> Option<PathBuf> {
    ["apptainer", "singularity"]
        .iter()
        .find_map(|p| crate::python_sync::on_path(p))
}

/// How the container node in `dir` runs here.
pub(crate) fn plan(dir: &Path, container: &Container, node: &str) -> Result<Plan, ContainerError> {
    let definition = dir.join(&container.def_file);
    let choice = std::env::var(CONTAINERS_ENV).unwrap_or_default();
    let runtime = match choice.as_str() {
        "" => runtime(),
        "native" => None,
        "apptainer" => Some(runtime().ok_or(ContainerError::NoRuntime)?),
        other => return Err(ContainerError::BadChoice(other.to_string())),
    };
    if let Some(runtime) = runtime {
        let text = std::fs::read(&definition).map_err(|source| ContainerError::Read {
            path: definition.clone(),
            source,
        })?;
        // One image per definition text: a changed definition is built again.
        let hash = &peppy_schema::sha256_hex(&text)[..16];
        let image = crate::sources::cache_dir()
            .join("containers")
            .join(format!("{}-{hash}.sif", node.replace(':', "-")));
        return Ok(Plan::Apptainer {
            runtime,
            image,
            definition,
        });
    }
    let text = std::fs::read_to_string(&definition).map_err(|source| ContainerError::Read {
        path: definition.clone(),
        source,
    })?;
    native(&parse(&text), &definition)
}

/// The line a launch prints for a container node's plan.
pub(crate) fn describe(node: &str, plan: &Plan) -> String {
    match plan {
        Plan::Native {
            build,
            run,
            skipped,
        } => {
            let build: Vec<String> = build.iter().map(|c| c.join(" ")).collect();
            let mut text = format!(
                "`{node}` declares a container; no container runtime is used here, so it runs natively: {}run `{}`",
                if build.is_empty() {
                    String::new()
                } else {
                    format!("build `{}`, ", build.join("; "))
                },
                run.join(" ")
            );
            if !skipped.is_empty() {
                text.push_str(&format!(
                    " (its image's own set-up is not done here: {})",
                    skipped.join("; ")
                ));
            }
            text
        }
        Plan::Apptainer { image, .. } => {
            format!("`{node}` runs in its container image {}", image.display())
        }
    }
}

/// The build commands of `plan` and the argv that starts the node, with
/// `extra` run arguments and mounts for Apptainer.
pub(crate) fn commands(plan: &Plan, container: &Container) -> (Vec<Vec<String>>, Vec<String>) {
    match plan {
        Plan::Native { build, run, .. } => (build.clone(), run.clone()),
        Plan::Apptainer {
            runtime,
            image,
            definition,
        } => {
            let runtime = runtime.display().to_string();
            let mut build = vec![runtime.clone(), "build".into(), "--force".into()];
            build.extend(container.apptainer_build_extra_args.iter().cloned());
            // Built beside its place and moved in once whole
            // ([`finish_build`]): an interrupted build is never taken for
            // an image.
            build.push(partial(image).display().to_string());
            build.push(definition.display().to_string());
            let mut run = vec![runtime, "run".into()];
            run.extend(container.apptainer_run_extra_args.iter().cloned());
            // Apptainer binds the working directory (the node's), the
            // home and /tmp itself; the document's mounts come on top.
            for mount in &container.mount_paths {
                run.extend(["--bind".into(), mount.clone()]);
            }
            run.push(image.display().to_string());
            (vec![build], run)
        }
    }
}

/// Whether `plan`'s image is built already: an image is built once per
/// definition.
pub(crate) fn built(plan: &Plan) -> bool {
    matches!(plan, Plan::Apptainer { image, .. } if image.is_file())
}

fn partial(image: &Path) -> PathBuf {
    image.with_extension("sif.partial")
}

/// Moves a whole built image into its place.
pub(crate) fn finish_build(plan: &Plan) -> std::io::Result<()> {
    match plan {
        Plan::Apptainer { image, .. } => std::fs::rename(partial(image), image),
        Plan::Native { .. } => Ok(()),
    }
}

/// Makes the directory `plan`'s image is built into.
pub(crate) fn make_image_dir(plan: &Plan) -> std::io::Result<()> {
    match plan {
        Plan::Apptainer { image, .. } => match image.parent() {
            Some(dir) => std::fs::create_dir_all(dir),
            None => Ok(()),
        },
        Plan::Native { .. } => Ok(()),
    }
}

/// Every container node of `stack`: how it runs here (a note each) and,
/// for one that cannot, a warning at its deployment (`up` refuses to
/// start a stack with one).
pub(crate) fn assess(stack: &peppy_schema::StackCheck) -> (Vec<String>, peppy_schema::Diagnostics) {
    let mut notes = Vec::new();
    let mut warnings = peppy_schema::Diagnostics::new();
    let mut seen = std::collections::HashSet::new();
    for (deployment, deployed) in stack.launcher.deployments.iter().zip(&stack.deployments) {
        let doc = &deployed.resolved.node;
        let peppy_schema::Launch::Container(container) = doc.execution.launch() else {
            continue;
        };
        let node = doc.identity().to_string();
        if !seen.insert(node.clone()) {
            continue;
        }
        match plan(&deployed.dir, container, &node) {
            Ok(plan) => notes.push(describe(&node, &plan)),
            Err(why) => warnings.push(
                deployment
                    .source_loc
                    .warning(
                        peppy_schema::Code::UnsupportedExecution,
                        format!("`{node}` runs in a container (`execution.container`) that cannot run here: {why}"),
                    )
                    .with_help("`check` plans it; `up` refuses to start a stack with it"),
            ),
        }
    }
    (notes, warnings)
}

#[cfg(test)]
mod tests {
    use super::*;

    const RUST: &str = r#"Bootstrap: docker
From: peppybot/rust-cargo-base

%files
    . /opt/realsense_d4xx

%post
    set -eux
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -y
    apt-get install -y --no-install-recommends libclang-dev \
        librealsense2-dev

    cd /opt/realsense_d4xx
    cargo build --release
    apt-get clean && rm -rf /var/lib/apt/lists/*

%runscript
    cd /opt/realsense_d4xx
    exec ./target/release/realsense_d4xx "$@"
"#;

    #[test]
    fn commands_joined_on_one_line_are_each_taken() {
        let def = "From: x\n%files\n  . /opt/n\n%post\n  cd /opt/n && cargo build --release; apt-get clean\n%runscript\n  exec python3 /opt/n/main.py\n";
        let Plan::Native {
            build,
            run,
            skipped,
        } = native(&parse(def), Path::new("n.def")).unwrap()
        else {
            panic!("native")
        };
        assert_eq!(build, [["cargo", "build", "--release"]]);
        assert_eq!(skipped, ["apt-get clean"]);
        assert_eq!(run, ["python3", "./main.py"]);
    }

    const PYTHON: &str = r#"Bootstrap: docker
From: peppybot/python-uv-base:latest
%files
    . /opt/recorder
%post
    export UV_PYTHON_INSTALL_DIR=/opt/uv-python
    cd /opt/recorder
    uv python install
    uv sync --no-editable --no-dev
%runscript
    cd /opt/recorder
    exec /opt/recorder/.venv/bin/python -u -m recorder
"#;

    #[test]
    fn a_cargo_definition_builds_and_runs_its_project_natively() {
        let plan = native(&parse(RUST), Path::new("apptainer.def")).unwrap();
        let Plan::Native {
            build,
            run,
            skipped,
        } = plan
        else {
            panic!("native")
        };
        assert_eq!(build, [["cargo", "build", "--release"]]);
        assert_eq!(run, ["./target/release/realsense_d4xx"]);
        assert_eq!(
            skipped,
            [
                "apt-get update -y",
                "apt-get install -y --no-install-recommends libclang-dev librealsense2-dev",
                "apt-get clean",
                "rm -rf /var/lib/apt/lists/*",
            ]
        );
    }

    #[test]
    fn a_uv_definition_syncs_and_runs_its_venv_natively() {
        let Plan::Native { build, run, .. } =
            native(&parse(PYTHON), Path::new("apptainer.def")).unwrap()
        else {
            panic!("native")
        };
        assert_eq!(build, [["uv", "sync", "--no-editable", "--no-dev"]]);
        assert_eq!(run, ["./.venv/bin/python", "-u", "-m", "recorder"]);
    }

    #[test]
    fn a_program_only_the_image_has_is_named() {
        let def = "From: nvcr.io/nvidia/isaac-sim:4.5.0\n%runscript\n    exec /isaac-sim/python.sh /opt/sim/run.py\n";
        match native(&parse(def), Path::new("sim.def")) {
            Err(ContainerError::Missing { program, image }) => {
                assert_eq!(program, "/isaac-sim/python.sh");
                assert_eq!(image, "nvcr.io/nvidia/isaac-sim:4.5.0");
            }
            other => panic!("{other:?}"),
        }
        assert!(matches!(
            native(
                &parse("From: x\n%post\n    cargo build\n"),
                Path::new("x.def")
            ),
            Err(ContainerError::NoRunscript { .. })
        ));
    }

    #[test]
    fn words_drop_quotes_and_keep_quoted_spaces() {
        assert_eq!(
            words(r#"exec ./x "a b" '$@'"#),
            ["exec", "./x", "a b", "$@"]
        );
    }
}
