//! `peppy-launch` as a library: validate peppy documents, check a launcher
//! end to end, and run, supervise and stop its node stack. The binary is a
//! thin wrapper around [`run`]; every command returns one typed error,
//! [`LaunchError`], whose [`LaunchError::exit_code`] is the only place exit
//! codes are decided.

mod build_progress;
mod check;
mod cli;
mod container;
mod control;
mod core_view;
mod detach;
mod drawing;
mod error;
mod executable;
mod find_launcher;
mod flows;
mod graph;
mod inspect;
mod local_links;
mod manage;
mod migrate;
mod node_init;
mod open_files;
mod output;
mod placement;
mod presence;
mod python_sync;
mod recording;
mod repo_index;
mod report;
mod repositories;
mod resolve;
mod run_node;
mod runs;
mod rust_libs;
mod security;
mod shared_build;
mod sources;
mod supervise;
mod up;
mod validate;

pub use cli::Cli;
pub use container::ContainerError;
pub use control::ControlError;
pub use detach::DetachError;
pub use error::{InspectError, LaunchError, Result, SetupError, UsageError, exit};
pub use executable::{ExecutableError, FindError};
pub use find_launcher::LauncherLookupError;
pub use inspect::SelectError;
pub use manage::ManageError;
pub use node_init::InitError;
pub use placement::{PlaceError, PlacementError};
pub use python_sync::{PackageError, RUNTIME_ENV, UV_VERSION, UvError, runtime_dir, uv};
pub use recording::RecordingError;
pub use recording::view::ViewError;
pub use repositories::RepoListError;
pub use run_node::LocateError;
pub use runs::LogsError;
pub use security::keys::KeysError;
pub use up::RouterError;

/// Runs one parsed command line.
pub fn run(cli: Cli) -> Result {
    open_files::raise();
    match cli.command {
        cli::Command::Validate(args) => validate::run(&args),
        cli::Command::Check(mut args) => {
            args.launcher = find_launcher::locate_searching(&args.launcher, &mut args.repos)?;
            check::run(&args)
        }
        cli::Command::Up(mut args) => {
            args.launcher = find_launcher::locate_searching(&args.launcher, &mut args.repos)
                .map_err(|e| {
                    if args.as_default_command {
                        find_launcher::maybe_a_command(e, &command_names())
                    } else {
                        e
                    }
                })?;
            up::run(&args)
        }
        cli::Command::Graph(mut args) => {
            if let Some(file) = &args.file {
                args.file = Some(find_launcher::locate_searching(file, &mut args.repos)?);
            }
            graph::run(&args)
        }
        cli::Command::Resolve(mut args) => {
            args.launcher = find_launcher::locate_searching(&args.launcher, &mut args.repos)?;
            resolve::run(&args)
        }
        cli::Command::Run(args) => run_node::run(&args),
        cli::Command::Plan(args) => run_node::plan(&args),
        cli::Command::Node(cli::NodeCommand::Init(args)) => node_init::run(&args),
        cli::Command::Node(cli::NodeCommand::List(args)) => inspect::node_list(args),
        cli::Command::Node(cli::NodeCommand::Info(args)) => inspect::node_info(args),
        cli::Command::Node(cli::NodeCommand::Stop(args)) => {
            manage::node(&args, |instance| control::Request::NodeStop { instance })
        }
        cli::Command::Node(cli::NodeCommand::Start(args)) => {
            manage::node(&args, |instance| control::Request::NodeStart { instance })
        }
        cli::Command::Node(cli::NodeCommand::Restart(args)) => {
            manage::node(&args, |instance| control::Request::NodeRestart { instance })
        }
        cli::Command::Stop(args) => manage::stop(&args),
        cli::Command::Topic(cmd) => inspect::topic(cmd),
        cli::Command::Service(cmd) => inspect::service(cmd),
        cli::Command::Action(cmd) => inspect::action(cmd),
        cli::Command::Sync(args) => python_sync::run(&args),
        cli::Command::Migrate(args) => migrate::run(&args),
        cli::Command::Router(args) => up::router(&args),
        cli::Command::Keys(mut args) => {
            args.launcher = find_launcher::locate(&args.launcher, &[])?;
            security::keys::run(&args)
        }
        cli::Command::Ps(args) => runs::ps(&args),
        cli::Command::Logs(args) => runs::logs(&args),
        cli::Command::Repo(cmd) => repo_index::run(&cmd),
        cli::Command::Record(args) => inspect::block_on_stream(recording::record::run(args)),
        cli::Command::Replay(args) => inspect::block_on_stream(recording::replay::run(args)),
        cli::Command::View(args) => inspect::block_on_stream(recording::view::run(args)),
    }
}

/// The tokio runtime a command runs its async part on. `workers`: its
/// thread count (`None`: one per core, for a launch that supervises many
/// instances; the inspection commands ask for two).
pub(crate) fn tokio_runtime(
    workers: Option<usize>,
) -> std::result::Result<tokio::runtime::Runtime, SetupError> {
    let mut builder = tokio::runtime::Builder::new_multi_thread();
    if let Some(n) = workers {
        builder.worker_threads(n);
    }
    builder.enable_all().build().map_err(SetupError::Runtime)
}

/// `peppy-launch LAUNCHER ...` means `peppy-launch up LAUNCHER ...`.
pub fn with_default_command(mut args: Vec<std::ffi::OsString>) -> Vec<std::ffi::OsString> {
    // The subcommands clap knows, so a new one is never mistaken for a launcher.
    let command = <Cli as clap::CommandFactory>::command();
    let known = |name: &str| {
        name == "help"
            || command
                .get_subcommands()
                .any(|c| c.get_name() == name || c.get_all_aliases().any(|a| a == name))
    };
    if let Some(first) = args.get(1).and_then(|a| a.to_str())
        && !first.starts_with('-')
        && !known(first)
    {
        args.insert(1, "up".into());
        args.insert(2, "--as-default-command".into());
    }
    args
}

/// The subcommands' names, for a mistyped one.
fn command_names() -> Vec<String> {
    <Cli as clap::CommandFactory>::command()
        .get_subcommands()
        .map(|c| c.get_name().to_string())
        .collect()
}
