//! `execution` (and the legacy `process`): language, build and run
//! commands, container, parameters; how a launcher starts the node.

use super::*;

/// `execution`.
#[derive(Debug, Clone)]
pub struct Execution {
    /// `rust`, `python`, ...
    pub language: String,
    /// Build argv, run in the node's directory.
    pub build_cmd: Option<Vec<String>>,
    /// Run argv, run in the node's directory.
    pub run_cmd: Option<Vec<String>>,
    /// Container settings (carried; running containers is out of scope).
    pub container: Option<Container>,
    /// Parameter schema.
    pub parameters: ParameterSchema,
}

/// How a launcher starts a node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Launch<'a> {
    /// `run_cmd`, run in the node's directory.
    Command(&'a [String]),
    /// A Rust node without `run_cmd`: the executable `cargo build` reports
    /// for the package in the node's directory.
    CargoBinary,
    /// `execution.container` (not started by peppy-launch yet).
    Container(&'a Container),
}

impl Execution {
    /// How a launcher starts the node.
    pub fn launch(&self) -> Launch<'_> {
        match (&self.run_cmd, &self.container) {
            (Some(argv), _) => Launch::Command(argv),
            (None, Some(c)) => Launch::Container(c),
            (None, None) => Launch::CargoBinary,
        }
    }

    /// The build to run before starting: `build_cmd`, or `cargo build` for
    /// a cargo-located Rust node that gives none.
    pub fn build_command(&self) -> Option<Vec<String>> {
        match (&self.build_cmd, self.launch()) {
            (Some(cmd), _) => Some(cmd.clone()),
            (None, Launch::CargoBinary) => Some(vec!["cargo".into(), "build".into()]),
            (None, _) => None,
        }
    }
}

/// `execution.container` (accepted and carried).
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Container {
    /// Definition file.
    pub def_file: String,
    /// Host paths to mount.
    pub mount_paths: Vec<String>,
    /// Extra `apptainer build` arguments.
    pub apptainer_build_extra_args: Vec<String>,
    /// Extra `apptainer run` arguments.
    pub apptainer_run_extra_args: Vec<String>,
    /// Extra `lima shell` arguments.
    pub lima_shell_extra_args: Vec<String>,
}

fn parse_command(r: &mut Reader<'_>, node: &Node, path: &str) -> Option<Vec<String>> {
    let argv = r.string_list(node, path)?;
    if argv.is_empty() || argv[0].trim().is_empty() {
        r.error(
            Code::EmptyCommand,
            node.span,
            path,
            format!("`{path}` must name a program: an argv like [\"cargo\", \"run\"]"),
        );
        return None;
    }
    Some(argv)
}

/// `cargo build ...` (what a cargo-located node's build must be).
fn is_cargo_build(argv: &[String]) -> bool {
    argv.first().is_some_and(|p| p == "cargo") && argv.get(1).is_some_and(|c| c == "build")
}

pub(super) fn parse_execution(r: &mut Reader<'_>, node: &Node) -> Option<Execution> {
    let obj = r.object(
        node,
        "execution",
        &[
            "language",
            "build_cmd",
            "run_cmd",
            "parameters",
            "container",
        ],
    )?;
    let mut ok = true;
    let language = r
        .required(&obj, "language")
        .and_then(|l| r.string(l, "execution.language"));
    if let Some(l) = &language
        && l.trim().is_empty()
    {
        r.error(
            Code::InvalidValue,
            obj.get("language").expect("present").span,
            "execution.language",
            "`execution.language` must not be empty",
        );
        ok = false;
    }
    let build_cmd = obj
        .get("build_cmd")
        .map(|b| parse_command(r, b, "execution.build_cmd"));
    let run_cmd = obj
        .get("run_cmd")
        .map(|b| parse_command(r, b, "execution.run_cmd"));
    let container = obj.get("container").map(|c| parse_container(r, c));
    let parameters = obj
        .get("parameters")
        .map(|p| parse_parameters(r, p, "execution.parameters"));
    match (&run_cmd, &container) {
        (Some(_), Some(_)) => {
            r.error_help(
                Code::ExecutionConflict,
                obj.member("container").expect("present").key_span,
                "execution.container",
                "`execution` has both `run_cmd` and `container`",
                "give exactly one: `run_cmd` for a process, `container` for a container",
            );
            ok = false;
        }
        // A Rust node built with cargo: the launcher learns its executable
        // from cargo's build messages.
        (None, None) if language.as_deref() == Some("rust") => {
            if let Some(Some(cmd)) = &build_cmd
                && !is_cargo_build(cmd)
            {
                r.error_help(
                    Code::ExecutionConflict,
                    obj.get("build_cmd").expect("present").span,
                    "execution.build_cmd",
                    "`execution` has no `run_cmd`, and `build_cmd` is not a `cargo build`",
                    "the executable of a Rust node without `run_cmd` is learned from `cargo build`: use `build_cmd: [\"cargo\", \"build\", ...]`, or give a `run_cmd`",
                );
                ok = false;
            }
        }
        (None, None) => {
            r.error_help(
                Code::ExecutionConflict,
                node.span,
                "execution",
                "`execution` has neither `run_cmd` nor `container`",
                "add `run_cmd: [\"./my_node\"]` (or a `container`); only `language: \"rust\"` nodes built with cargo may omit it",
            );
            ok = false;
        }
        _ => {}
    }
    let build_cmd = match build_cmd {
        Some(None) => {
            ok = false;
            None
        }
        Some(v) => v,
        None => None,
    };
    let run_cmd = match run_cmd {
        Some(None) => {
            ok = false;
            None
        }
        Some(v) => v,
        None => None,
    };
    let container = match container {
        Some(None) => {
            ok = false;
            None
        }
        Some(v) => v,
        None => None,
    };
    let parameters = match parameters {
        Some(None) => {
            ok = false;
            ParameterSchema::default()
        }
        Some(Some(p)) => p,
        None => ParameterSchema::default(),
    };
    let language = language?;
    ok.then_some(Execution {
        language,
        build_cmd,
        run_cmd,
        container,
        parameters,
    })
}

fn parse_container(r: &mut Reader<'_>, node: &Node) -> Option<Container> {
    let path = "execution.container";
    let obj = r.object(
        node,
        path,
        &[
            "def_file",
            "mount_paths",
            "apptainer_build_extra_args",
            "apptainer_run_extra_args",
            "lima_shell_extra_args",
        ],
    )?;
    let def_file = r
        .required(&obj, "def_file")
        .and_then(|d| r.string(d, &obj.path_of("def_file")));
    let mut list = |key: &str| -> Option<Vec<String>> {
        match obj.get(key) {
            Some(n) => r.string_list(n, &obj.path_of(key)),
            None => Some(Vec::new()),
        }
    };
    let mount_paths = list("mount_paths");
    let build = list("apptainer_build_extra_args");
    let run = list("apptainer_run_extra_args");
    let lima = list("lima_shell_extra_args");
    Some(Container {
        def_file: def_file?,
        mount_paths: mount_paths?,
        apptainer_build_extra_args: build?,
        apptainer_run_extra_args: run?,
        lima_shell_extra_args: lima?,
    })
}

pub(super) fn parse_legacy_process(
    r: &mut Reader<'_>,
    root: &Obj<'_>,
    language: Option<String>,
) -> Option<Execution> {
    let language = match language {
        Some(l) => Some(l),
        None => {
            if let Some(m) = root.get("manifest")
                && m.get("language").is_none()
            {
                r.error(
                    Code::MissingKey,
                    m.span,
                    "manifest",
                    "missing required key `language` in `manifest` (legacy form)",
                );
            }
            None
        }
    };
    let process = r.required(root, "process")?;
    let obj = r.object(process, "process", &["add_cmd", "start_cmd"])?;
    let mut ok = true;
    let build_cmd = match obj.member("add_cmd") {
        Some(m) => {
            r.warn_help(
                Code::LegacySpelling,
                m.key_span,
                "process.add_cmd",
                format!("{LEGACY_HELP}: `process.add_cmd`"),
                "write `execution.build_cmd`",
            );
            let v = parse_command(r, &m.value, "process.add_cmd");
            ok &= v.is_some();
            v
        }
        None => None,
    };
    let run_cmd = match r.required(&obj, "start_cmd") {
        Some(n) => {
            let m = obj.member("start_cmd").expect("present");
            r.warn_help(
                Code::LegacySpelling,
                m.key_span,
                "process.start_cmd",
                format!("{LEGACY_HELP}: `process.start_cmd`"),
                "write `execution.run_cmd`",
            );
            parse_command(r, n, "process.start_cmd")
        }
        None => None,
    };
    if let Some(m) = root.member("process") {
        r.warn_help(
            Code::LegacySpelling,
            m.key_span,
            "process",
            format!("{LEGACY_HELP}: `process`"),
            "write `execution`",
        );
    }
    let language = language?;
    let run_cmd = run_cmd?;
    ok.then_some(Execution {
        language,
        build_cmd,
        run_cmd: Some(run_cmd),
        container: None,
        parameters: ParameterSchema::default(),
    })
}
