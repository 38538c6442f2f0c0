//! Command-line interface.

use std::path::PathBuf;
use std::time::Duration;

use clap::{Args, Parser, Subcommand, ValueEnum};

/// Validate, check and run stacks of peppy nodes.
#[derive(Debug, Parser)]
#[command(name = "peppy-launch", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub(crate) command: Command,
}

#[derive(Debug, Subcommand)]
pub(crate) enum Command {
    /// Validate peppy documents (nodes, interfaces, launchers, repository
    /// lists). A directory means every document in it, recursively.
    ///
    /// Exit code 0 when every document is valid, 2 otherwise.
    Validate(ValidateArgs),
    /// Check a launcher end to end: resolve every deployment's node through
    /// its source and the repositories, resolve every node, check every
    /// binding rule and parameter, and print the binding plan.
    ///
    /// Exit code 0 when the stack is valid, 2 otherwise.
    Check(CheckArgs),
    /// Run a launcher: check everything (start nothing if anything is
    /// wrong), build each node once, start every instance with its
    /// bindings, parameters, namespace and Zenoh endpoints, multiplex their
    /// output, supervise, and stop cleanly on Ctrl-C.
    ///
    /// `peppy-launch LAUNCHER` is the same. Exit codes: 0 clean stop,
    /// 1 an instance failed (or its restart budget ran out), 2 invalid.
    Up(UpArgs),
    /// Run one node (a `name:tag` from the repositories, or a path) with
    /// the same checks of its bindings and parameters as a launcher, e.g.
    /// `peppy-launch run video_reconstruction:v1 --instance-id rec_1 --bind rear_camera@cam_1`.
    /// Without `--connect` it joins (or hosts) the local hub on
    /// tcp/127.0.0.1:7447, so several `run`s find each other.
    Run(RunArgs),
    /// Print the plan a standalone command line gives a node: its slots
    /// (bindings and filters, decided by the launcher's binding engine),
    /// its checked parameters, its identity and endpoints, as the JSON a
    /// launch hands each instance. A Python node started by hand asks this
    /// for its plan, so every node binds through one engine, e.g.
    /// `peppy-launch plan examples/nodes/video_reconstruction -- --bind left_cam@rs_left`.
    Plan(PlanArgs),
    /// Print the flat launcher a selection of a composed launcher gives
    /// (valid input for `check` and `up`) on stdout, and on stderr which
    /// options were chosen, what each adjustment did and which constraints
    /// were checked, e.g. `peppy-launch resolve openarm_v2.json5 --with
    /// mujoco,web_commander`. `--list` prints every selection instead.
    ///
    /// Exit code 0 when it resolves, 2 otherwise.
    Resolve(ResolveArgs),
    /// Draw the stack: instances, bindings, dashed `(any)` edges for
    /// unbound from_any slots, dotted edges for external topics; `--live`
    /// draws the running stack with measured rates. DOT on stdout, or
    /// `-o FILE` with `.svg` / `.html` (drawn without Graphviz) or `.dot`.
    Graph(GraphArgs),
    /// Nodes: create one (`node init NAME`); the instances of running
    /// stacks (`node list`, `node info`, `node stop|start|restart`).
    #[command(subcommand)]
    Node(NodeCommand),
    /// Topics of a running stack: list, echo, hz, bw, pub.
    #[command(subcommand)]
    Topic(TopicCommand),
    /// Services of a running stack: list, call.
    #[command(subcommand)]
    Service(ServiceCommand),
    /// Actions of a running stack: list, send-goal.
    #[command(subcommand)]
    Action(ActionCommand),
    /// Write a node's generated API where its build takes it from (`up`
    /// and `run` do it before building): the `.peppy/libs/peppygen` and
    /// `.peppy/libs/peppylib` crates or projects when its Cargo.toml or
    /// pyproject.toml takes them from there, else a Python node's
    /// `peppygen` package beside its `peppy.json5`. A Rust node using
    /// build.rs or `#[peppy::node]` generates its API when it builds.
    Sync(SyncArgs),
    /// Rewrite documents of the underscored spelling (`node_v1`,
    /// `interface_v1`, `launcher_v1`) in the slashed one (`node/v1`,
    /// `contract/v1`, `launcher/v1`): printed on stdout, or in place with
    /// `--write`. What the slashed spelling cannot say is reported on
    /// stderr, located. Comments are kept.
    Migrate(MigrateArgs),
    /// Run a bare Zenoh router for core nodes to meet at, where they cannot
    /// reach each other directly (give each launch `--connect` to it); a
    /// stand-in for `zenohd`.
    Router(RouterArgs),
    /// Create the keys a secured stack's core nodes link with (once, on one
    /// machine; then copy the printed directory to every machine).
    Keys(KeysArgs),
    /// Stop a running launch as Ctrl-C in its terminal does (consumers
    /// first, shutdown hooks within their window), and wait until it has
    /// ended. A detached launch's output is shown meanwhile.
    Stop(StopArgs),
    /// The launches running on this machine, with their instances.
    Ps(PsArgs),
    /// An instance's output, from its launch's run directory.
    Logs(LogsArgs),
    /// Repositories: the ones searched (`repo list`), the user's list of
    /// folders and git repositories (`repo add|remove|refresh`), and a
    /// repository's index (`repo index DIR`).
    #[command(subcommand)]
    Repo(RepoCommand),
    /// Record a running stack's topics into an MCAP file, until Ctrl-C,
    /// `--duration` or `--max-size`: every topic, or those named. Each
    /// message is kept as JSON with a JSON Schema of its format, so
    /// Foxglove and the MCAP tools read it without peppy, e.g.
    /// `peppy-launch record -o run.mcap --duration 10 video_stream`.
    Record(RecordArgs),
    /// Publish a recording into a running stack as its recorded producers,
    /// at the recorded pace, after checking that every consumer reads the
    /// recorded formats, e.g. `peppy-launch replay run.mcap --rate 2`.
    Replay(ReplayArgs),
    /// Serve a running stack live to Foxglove (the Foxglove WebSocket
    /// protocol): every topic a channel, decoded as `record` writes it,
    /// camera-like messages also as images, services callable.
    View(ViewArgs),
}

#[derive(Debug, Args)]
pub(crate) struct ViewArgs {
    /// Topics to serve (default: every topic), as `record` names them.
    #[arg(value_name = "TOPIC")]
    pub(crate) topics: Vec<String>,
    /// The address to serve on. The protocol has no login: another
    /// address than loopback (`0.0.0.0`) shows the stack to whoever reaches
    /// it, which a secured stack refuses.
    #[arg(long, value_name = "HOST", default_value = "127.0.0.1")]
    pub(crate) host: String,
    /// The port to serve on (Foxglove's default is 8765; 0 picks a free
    /// one, printed).
    #[arg(long, value_name = "PORT", default_value_t = 8765)]
    pub(crate) port: u16,
    #[command(flatten)]
    pub(crate) stack: StackArgs,
}

#[derive(Debug, Args)]
pub(crate) struct RecordArgs {
    /// Topics to record (default: every topic): `NAME`, or
    /// `INSTANCE/NAME` for one producer's; `*` and `?` are wildcards
    /// (`video_*`, `rs_*/video_stream`).
    #[arg(value_name = "TOPIC")]
    pub(crate) topics: Vec<String>,
    /// The file to write (default: `<namespace>-<UTC time>.mcap` here).
    #[arg(short = 'o', long, value_name = "FILE")]
    pub(crate) output: Option<PathBuf>,
    /// Overwrite the file if it exists.
    #[arg(long)]
    pub(crate) force: bool,
    /// Stop after this many seconds.
    #[arg(long, value_name = "SECONDS", value_parser = parse_duration)]
    pub(crate) duration: Option<Duration>,
    /// Stop once the file reaches this size (`500M`, `2G`, bytes).
    #[arg(long, value_name = "SIZE", value_parser = parse_size)]
    pub(crate) max_size: Option<u64>,
    #[command(flatten)]
    pub(crate) stack: StackArgs,
}

#[derive(Debug, Args)]
pub(crate) struct ReplayArgs {
    /// The recording (an MCAP file `record` wrote).
    #[arg(value_name = "FILE")]
    pub(crate) file: PathBuf,
    /// Topics to replay (default: all), as `record` names them.
    #[arg(value_name = "TOPIC")]
    pub(crate) topics: Vec<String>,
    /// Publish a recorded producer's messages as another instance:
    /// `OLD=NEW` (repeatable).
    #[arg(long = "as", value_name = "OLD=NEW")]
    pub(crate) renames: Vec<String>,
    /// Speed factor: 2 plays twice as fast, 0.5 at half speed.
    #[arg(long, value_name = "FACTOR", default_value_t = 1.0)]
    pub(crate) rate: f64,
    /// Start this many seconds into the recording.
    #[arg(long, value_name = "SECONDS", default_value = "0", value_parser = parse_offset)]
    pub(crate) start: Duration,
    /// End this many seconds into the recording.
    #[arg(long, value_name = "SECONDS", value_parser = parse_offset)]
    pub(crate) end: Option<Duration>,
    /// Play the recording again and again, until Ctrl-C.
    #[arg(long = "loop", conflicts_with = "clock")]
    pub(crate) r#loop: bool,
    /// Drive the stack's sim time from the recording (nodes with
    /// `use_sim_time` follow the recording's clock).
    #[arg(long)]
    pub(crate) clock: bool,
    #[command(flatten)]
    pub(crate) stack: StackArgs,
}

/// Which running stack to look at. Without any of these: the only launch
/// running on this machine, else the local hub of `peppy-launch run`.
#[derive(Debug, Clone, Args)]
pub(crate) struct StackArgs {
    /// The stack started from this launcher file.
    #[arg(short = 'l', long, value_name = "LAUNCHER")]
    pub(crate) launcher: Option<PathBuf>,
    /// The stack's namespace.
    #[arg(long, value_name = "NS")]
    pub(crate) namespace: Option<String>,
    /// Reach the stack through these Zenoh endpoints (e.g. another
    /// machine's launch: `tcp/192.0.2.10:7447`; repeatable).
    #[arg(long, value_name = "ENDPOINT")]
    pub(crate) connect: Vec<String>,
    /// How long to wait for instances to answer.
    #[arg(long, value_name = "SECONDS", default_value = "2", value_parser = parse_wait)]
    pub(crate) wait: Duration,
}

/// How long a streaming command runs.
#[derive(Debug, Clone, Args)]
pub(crate) struct StreamArgs {
    /// Stop after N messages (or reports).
    #[arg(long, value_name = "N")]
    pub(crate) count: Option<u64>,
    /// Stop after this many seconds; with `--count`, fewer than N by then
    /// is a failure (exit 1).
    #[arg(long, value_name = "SECONDS", value_parser = parse_wait)]
    pub(crate) timeout: Option<Duration>,
}

#[derive(Debug, Args)]
pub(crate) struct PlanArgs {
    /// The node: its directory or `peppy.json5`, or a `name:tag` from the
    /// repositories.
    #[arg(value_name = "NODE", required_unless_present = "model")]
    pub(crate) node: Option<String>,
    /// The node's model as its generated code carries it (JSON; `-` reads
    /// standard input), instead of NODE's documents.
    #[arg(long, value_name = "FILE", conflicts_with = "node")]
    pub(crate) model: Option<PathBuf>,
    /// An extra repository directory (repeatable).
    #[arg(long = "repo", value_name = "DIR")]
    pub(crate) repos: Vec<PathBuf>,
    /// The node's own command line, after `--`: `--instance-id`, `--bind
    /// KEY@INSTANCE`, `--params FILE`, `--namespace`, `--connect`,
    /// `--listen`, `key=value`.
    #[arg(last = true, value_name = "NODE_ARGS")]
    pub(crate) args: Vec<String>,
}

#[derive(Debug, Subcommand)]
pub(crate) enum RepoCommand {
    /// Write DIR's index, `peppy_repository.json5` (`repository/v1`): every
    /// node, contract, pairing and MCP exposure under DIR by `name` and
    /// `tag`, every launcher by file stem (hidden and build directories are
    /// skipped). With `--check`, write nothing and report every drift of
    /// the committed index instead.
    ///
    /// Exit code 0 when written (or current), 2 when DIR cannot be indexed
    /// or `--check` finds drift, 1 when the file cannot be written.
    Index(RepoIndexArgs),
    /// Every repository a command run here searches, in order: `--repo`
    /// folders, `PEPPY_REPOSITORIES`, the nearest
    /// `peppy_repositories.json5`, then the user's list (the public hubs
    /// while the user has no list); who listed each and what it holds.
    /// Reads the cache only.
    List(RepoListArgs),
    /// Add a folder or a git repository (`URL [--ref REF]`, fetched now)
    /// to the user's list.
    Add(RepoAddArgs),
    /// Take repositories off the user's list (a public hub too: that turns
    /// it off), by short name (`nodes-hub`), URL or folder.
    Remove(RepoRemoveArgs),
    /// Fetch every git repository a command run here searches, and say
    /// which commit each is read at. One that cannot be reached keeps its
    /// cached copy.
    Refresh(RepoRefreshArgs),
}

#[derive(Debug, Args)]
pub(crate) struct RepoListArgs {
    /// An extra repository directory (repeatable), searched first.
    #[arg(long = "repo", value_name = "DIR")]
    pub(crate) repos: Vec<PathBuf>,
}

#[derive(Debug, Args)]
pub(crate) struct RepoAddArgs {
    /// A folder, or anything `git clone` takes (a URL, a bare
    /// repository's path).
    #[arg(value_name = "LOCATION")]
    pub(crate) location: String,
    /// The branch, tag or full commit id to read (a git repository; the
    /// default branch when not given).
    #[arg(long = "ref", value_name = "REF")]
    pub(crate) reference: Option<String>,
}

#[derive(Debug, Args)]
pub(crate) struct RepoRemoveArgs {
    /// Repositories to remove: short names, URLs or folders.
    #[arg(value_name = "NAME", required_unless_present = "all")]
    pub(crate) names: Vec<String>,
    /// Empty the list (the public hubs included).
    #[arg(long)]
    pub(crate) all: bool,
}

#[derive(Debug, Args)]
pub(crate) struct RepoRefreshArgs {
    /// An extra repository directory (repeatable).
    #[arg(long = "repo", value_name = "DIR")]
    pub(crate) repos: Vec<PathBuf>,
}

#[derive(Debug, Args)]
pub(crate) struct RepoIndexArgs {
    /// The repository's root directory.
    #[arg(value_name = "DIR", default_value = ".")]
    pub(crate) dir: PathBuf,
    /// Write nothing: compare the committed index with what DIR declares
    /// and report every entry that is unlisted, moved or unmatched.
    #[arg(long)]
    pub(crate) check: bool,
}

#[derive(Debug, Args)]
pub(crate) struct MigrateArgs {
    /// Documents to migrate (a node's directory means its `peppy.json5`).
    #[arg(value_name = "FILE", required = true)]
    pub(crate) files: Vec<PathBuf>,
    /// Rewrite the files in place instead of printing them.
    #[arg(long)]
    pub(crate) write: bool,
    /// An extra repository directory, searched for the contracts nodes
    /// conform to and the nodes launchers deploy (repeatable).
    #[arg(long = "repo", value_name = "DIR")]
    pub(crate) repos: Vec<PathBuf>,
}

#[derive(Debug, Args)]
pub(crate) struct SyncArgs {
    /// The node: its directory or `peppy.json5`, or a `name:tag` from the
    /// repositories.
    #[arg(value_name = "NODE")]
    pub(crate) node: PathBuf,
    /// An extra repository directory (repeatable).
    #[arg(long = "repo", value_name = "DIR")]
    pub(crate) repos: Vec<PathBuf>,
}

#[derive(Debug, Subcommand)]
pub(crate) enum NodeCommand {
    /// Running instances: node, core node, pid, uptime, entries.
    List(ListArgs),
    /// One instance in full: slots and bindings, topics, services, actions.
    Info(NodeInfoArgs),
    /// Stop one instance of a running launch (as the launch would stop
    /// it: its hooks get their window); the launch goes on, and `node
    /// start` starts it again.
    Stop(NodeControlArgs),
    /// Start an instance `node stop` stopped.
    Start(NodeControlArgs),
    /// Stop an instance and start it again.
    Restart(NodeControlArgs),
    /// Create a node: a folder NAME with its `peppy.json5` (`node/v1`), a
    /// node that greets and hears its peers, its `.peppy/libs`, and a test
    /// under the generated harness (`cargo test`, or `uv run --group dev
    /// pytest`). Never overwrites.
    #[command(visible_alias = "create")]
    Init(InitArgs),
}

#[derive(Debug, Args)]
pub(crate) struct NodeControlArgs {
    /// The instance id.
    #[arg(value_name = "INSTANCE")]
    pub(crate) instance: String,
    /// The launch that runs it, when several have one of that id: its pid,
    /// namespace, launcher path or launcher name.
    #[arg(long, value_name = "LAUNCH")]
    pub(crate) launch: Option<String>,
}

#[derive(Debug, Args)]
pub(crate) struct StopArgs {
    /// The launch: its pid, namespace, launcher path or launcher name
    /// (default: the only one running).
    #[arg(value_name = "LAUNCH")]
    pub(crate) launch: Option<String>,
    /// How long to wait for it to end.
    #[arg(long, value_name = "SECONDS", default_value = "120", value_parser = parse_wait)]
    pub(crate) timeout: Duration,
}

/// What `node init` writes a node with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub(crate) enum Toolchain {
    /// A Rust node: a cargo project.
    #[default]
    Cargo,
    /// A Python node: a uv project.
    Uv,
}

#[derive(Debug, Args)]
pub(crate) struct InitArgs {
    /// The node's name, and its folder's: a letter first, then letters,
    /// digits, `_` and `-`.
    #[arg(value_name = "NAME")]
    pub(crate) name: String,
    /// The toolchain the node is built and tested with.
    #[arg(long, value_enum, default_value_t)]
    pub(crate) toolchain: Toolchain,
    /// Where the node's folder goes (default: here).
    #[arg(long, value_name = "DIR")]
    pub(crate) to_dir: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub(crate) struct ListArgs {
    #[command(flatten)]
    pub(crate) stack: StackArgs,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Human)]
    pub(crate) format: Format,
}

#[derive(Debug, Args)]
pub(crate) struct NodeInfoArgs {
    /// The instance id.
    #[arg(value_name = "INSTANCE")]
    pub(crate) instance: String,
    #[command(flatten)]
    pub(crate) stack: StackArgs,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Human)]
    pub(crate) format: Format,
}

#[derive(Debug, Subcommand)]
pub(crate) enum TopicCommand {
    /// Every topic: owner, format, QoS, producers and consumers.
    List(ListArgs),
    /// Print the messages of a topic, decoded.
    Echo(EchoArgs),
    /// Message rate per producer.
    Hz(RateArgs),
    /// Bandwidth per producer.
    Bw(RateArgs),
    /// Publish a message given as JSON5, checked against the topic's format.
    Pub(PubArgs),
}

/// Which topic's samples to take.
#[derive(Debug, Clone, Args)]
pub(crate) struct TopicSelect {
    /// The topic: `NAME` (every owner's), or `OWNER/NAME`
    /// (`depth_camera:v1/video_stream`); `node/OWNER/NAME` or
    /// `interface/OWNER/NAME` when a node and an interface share a name.
    #[arg(value_name = "TOPIC")]
    pub(crate) topic: String,
    /// Only this producer instance.
    #[arg(long, value_name = "INSTANCE")]
    pub(crate) from: Option<String>,
    /// Only what this consumer's slot receives: `INSTANCE.SLOT`
    /// (`recon.left_cam`), or `INSTANCE` for its external topic.
    #[arg(long, value_name = "INSTANCE.SLOT")]
    pub(crate) slot: Option<String>,
    /// A pair's topic: `TOPIC` is a topic of the pairing this pairing slot
    /// takes part in (`leader.follower`), shown as the pair carries it
    /// (sent by the slot, or by its peer); an observer slot: as its
    /// sources send it. Its format is read from the pairing document.
    #[arg(long, value_name = "INSTANCE.SLOT", conflicts_with_all = ["slot", "from"])]
    pub(crate) pair: Option<String>,
    /// With `--pair`: a repository to find the pairing document in
    /// (repeatable; default: `PEPPY_REPOSITORIES`, else the
    /// `peppy_repositories.json5` of the current directory or above).
    #[arg(long = "repo", value_name = "DIR", requires = "pair")]
    pub(crate) repos: Vec<PathBuf>,
}

#[derive(Debug, Args)]
pub(crate) struct EchoArgs {
    #[command(flatten)]
    pub(crate) select: TopicSelect,
    /// Stop after the first message.
    #[arg(long)]
    pub(crate) once: bool,
    #[command(flatten)]
    pub(crate) stream: StreamArgs,
    #[command(flatten)]
    pub(crate) stack: StackArgs,
    /// `human`: YAML-like text; `json`: one JSON object per line.
    #[arg(long, value_enum, default_value_t = Format::Human)]
    pub(crate) format: Format,
}

#[derive(Debug, Args)]
pub(crate) struct RateArgs {
    #[command(flatten)]
    pub(crate) select: TopicSelect,
    /// Seconds between reports.
    #[arg(long, value_name = "SECONDS", default_value = "1", value_parser = parse_wait)]
    pub(crate) interval: Duration,
    /// Compute over the last N messages of each producer.
    #[arg(long, value_name = "N", default_value_t = 1000)]
    pub(crate) window: usize,
    #[command(flatten)]
    pub(crate) stream: StreamArgs,
    #[command(flatten)]
    pub(crate) stack: StackArgs,
    /// `human`: a table (refreshed in place on a terminal); `json`: one
    /// report per line.
    #[arg(long, value_enum, default_value_t = Format::Human)]
    pub(crate) format: Format,
}

#[derive(Debug, Args)]
pub(crate) struct PubArgs {
    /// The topic: `NAME` or `OWNER/NAME`.
    #[arg(value_name = "TOPIC")]
    pub(crate) topic: String,
    /// The message, as JSON5 (`'{ positions: [0.1, 0.2] }'`); may be
    /// omitted for a topic without payload.
    #[arg(value_name = "JSON5")]
    pub(crate) value: Option<String>,
    /// Publish as this producer instance (consumers bound to it receive
    /// it); default: the topic's only producer.
    #[arg(long = "as", value_name = "INSTANCE")]
    pub(crate) as_instance: Option<String>,
    /// Publish repeatedly at this rate (default: once).
    #[arg(long, value_name = "HZ")]
    pub(crate) rate: Option<f64>,
    #[command(flatten)]
    pub(crate) stream: StreamArgs,
    #[command(flatten)]
    pub(crate) stack: StackArgs,
}

#[derive(Debug, Subcommand)]
pub(crate) enum ServiceCommand {
    /// Every service: server, request and response formats.
    List(ListArgs),
    /// Call a service once and print the response.
    Call(CallArgs),
}

#[derive(Debug, Args)]
pub(crate) struct CallArgs {
    /// The serving instance.
    #[arg(value_name = "INSTANCE")]
    pub(crate) instance: String,
    /// The service.
    #[arg(value_name = "SERVICE")]
    pub(crate) service: String,
    /// The request, as JSON5; omit it when the service takes no request.
    #[arg(value_name = "JSON5")]
    pub(crate) value: Option<String>,
    /// Seconds to wait for the response.
    #[arg(long, value_name = "SECONDS", default_value = "10", value_parser = parse_wait)]
    pub(crate) timeout: Duration,
    #[command(flatten)]
    pub(crate) stack: StackArgs,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Human)]
    pub(crate) format: Format,
}

#[derive(Debug, Subcommand)]
pub(crate) enum ActionCommand {
    /// Every action: server, goal, feedback and result formats.
    List(ListArgs),
    /// Send a goal, print feedback as it comes and the result at the end
    /// (Ctrl-C cancels the goal).
    SendGoal(GoalArgs),
}

#[derive(Debug, Args)]
pub(crate) struct GoalArgs {
    /// The serving instance.
    #[arg(value_name = "INSTANCE")]
    pub(crate) instance: String,
    /// The action.
    #[arg(value_name = "ACTION")]
    pub(crate) action: String,
    /// The goal, as JSON5; omit it when the goal has no fields.
    #[arg(value_name = "JSON5")]
    pub(crate) value: Option<String>,
    /// Seconds to wait for the result.
    #[arg(long, value_name = "SECONDS", default_value = "60", value_parser = parse_wait)]
    pub(crate) timeout: Duration,
    #[command(flatten)]
    pub(crate) stack: StackArgs,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Human)]
    pub(crate) format: Format,
}

#[derive(Debug, Args)]
pub(crate) struct RouterArgs {
    /// Where it listens (repeatable), e.g. `tcp/0.0.0.0:7447`.
    #[arg(long, value_name = "ENDPOINT", required = true)]
    pub(crate) listen: Vec<String>,
    /// Other routers to link to (repeatable).
    #[arg(long, value_name = "ENDPOINT")]
    pub(crate) connect: Vec<String>,
}

#[derive(Debug, Args)]
pub(crate) struct KeysArgs {
    /// The launcher (with `core_nodes`): its file, or its name in the
    /// repositories.
    #[arg(value_name = "LAUNCHER")]
    pub(crate) launcher: PathBuf,
    /// Replace existing keys (every machine then needs the new copy).
    #[arg(long)]
    pub(crate) rotate: bool,
    // Placement (`--place`): the keys are the machines'.
    #[command(flatten)]
    pub(crate) placing: PlaceArgs,
}

#[derive(Debug, Args)]
pub(crate) struct PsArgs {
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Human)]
    pub(crate) format: Format,
}

#[derive(Debug, Args)]
pub(crate) struct LogsArgs {
    /// The instance id.
    #[arg(value_name = "INSTANCE")]
    pub(crate) instance: String,
    /// Read the newest run of this launcher (running or not).
    #[arg(short = 'l', long, value_name = "LAUNCHER")]
    pub(crate) launcher: Option<PathBuf>,
    /// Keep printing what the instance writes.
    #[arg(short, long)]
    pub(crate) follow: bool,
    /// Start with the last N lines (default: the whole log).
    #[arg(long, value_name = "N")]
    pub(crate) tail: Option<usize>,
    #[command(flatten)]
    pub(crate) stream: StreamArgs,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum Format {
    /// For people: tables, text, diagnostics with source snippets.
    Human,
    /// For programs: JSON on stdout (one value per line when streaming).
    Json,
}

#[derive(Debug, Args)]
pub(crate) struct ValidateArgs {
    /// Files or directories to validate.
    #[arg(required = true, value_name = "PATH")]
    pub(crate) paths: Vec<PathBuf>,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Human)]
    pub(crate) format: Format,
}

#[derive(Debug, Args)]
pub(crate) struct CheckArgs {
    /// The launcher: its file, or its name (file stem) in the
    /// repositories.
    #[arg(value_name = "LAUNCHER")]
    pub(crate) launcher: PathBuf,
    /// Choose options of a composed launcher's axes: `option` or
    /// `axis=option`, comma-separated, repeatable (`--with mujoco,cameras=sim_cameras`).
    #[arg(long = "with", value_name = "OPTIONS")]
    pub(crate) with: Vec<String>,
    /// Check every selection the launcher's constraints allow, one after
    /// another (those they refuse are listed with their reason).
    #[arg(long, conflicts_with = "with")]
    pub(crate) all_selections: bool,
    /// An extra repository directory, searched before PEPPY_REPOSITORIES and
    /// the nearest peppy_repositories.json5 (repeatable).
    #[arg(long = "repo", value_name = "DIR")]
    pub(crate) repos: Vec<PathBuf>,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Human)]
    pub(crate) format: Format,
    /// Also print the access policy `up` would enforce with security on:
    /// per instance, what it may emit, serve, receive and call.
    #[arg(long)]
    pub(crate) security: bool,
    /// The namespace the policy's keys are under (default: the one `up`
    /// derives).
    #[arg(long, value_name = "NS")]
    pub(crate) namespace: Option<String>,
    // Placement (`--place`).
    #[command(flatten)]
    pub(crate) placing: PlaceArgs,
}

#[derive(Debug, Clone, Args)]
pub(crate) struct UpArgs {
    /// The launcher: its file, or its name (file stem) in the
    /// repositories.
    #[arg(value_name = "LAUNCHER")]
    pub(crate) launcher: PathBuf,
    /// Set when `up` was not written (`peppy-launch LAUNCHER`): a word that
    /// names no launcher may be a mistyped command.
    #[arg(long = "as-default-command", hide = true)]
    pub(crate) as_default_command: bool,
    /// Choose options of a composed launcher's axes: `option` or
    /// `axis=option`, comma-separated, repeatable (`--with mujoco,cameras=sim_cameras`).
    #[arg(long = "with", value_name = "OPTIONS")]
    pub(crate) with: Vec<String>,
    /// An extra repository directory (repeatable).
    #[arg(long = "repo", value_name = "DIR")]
    pub(crate) repos: Vec<PathBuf>,
    /// Skip the nodes' build commands.
    #[arg(long)]
    pub(crate) no_build: bool,
    /// Run in the background: return once every instance has started
    /// (or with the reason it could not), leaving the launch running with
    /// its output in its run directory. `ps`, `logs`, `node stop|start`
    /// and `stop` reach it.
    #[arg(short = 'd', long)]
    pub(crate) detach: bool,
    /// The namespace to run in (default: derived from the launcher path).
    #[arg(long, value_name = "NS")]
    pub(crate) namespace: Option<String>,
    /// Where the launch's Zenoh router listens (repeatable; default a free
    /// loopback port). Listen on a LAN address to let other hosts join.
    #[arg(long, value_name = "ENDPOINT")]
    pub(crate) listen: Vec<String>,
    /// Another router or peer to connect to, e.g. a zenohd or another
    /// host's launch (repeatable).
    #[arg(long, value_name = "ENDPOINT")]
    pub(crate) connect: Vec<String>,
    /// Seconds between SIGINT and SIGTERM when stopping; never less than a
    /// node's shutdown-hook window plus 2 s (7 s for the default window).
    #[arg(long, value_name = "SECONDS", default_value = "5", value_parser = parse_grace)]
    pub(crate) grace: Duration,
    /// For a launcher with `core_nodes`: start this machine's share (its
    /// instances and its router, linked to the others as the launcher or
    /// `--listen` / `--connect` say). With `--place`, the name of this
    /// machine (what `@self` means; default: its host name).
    #[arg(long, value_name = "NAME", conflicts_with = "local")]
    pub(crate) core_node: Option<String>,
    /// For a launcher with `core_nodes`: start every machine's share here,
    /// each instance still named by its core node (for development).
    #[arg(long, conflicts_with = "place")]
    pub(crate) local: bool,
    /// Run without security even where it would be on (a router reachable
    /// beyond loopback): any process that reaches the router can then read
    /// and write every topic of the stack.
    #[arg(long)]
    pub(crate) insecure: bool,
    /// Also serve the stack to Foxglove (as `peppy-launch view` does) on
    /// a loopback port: `--view` (8765) or `--view=PORT`.
    #[arg(
        long,
        value_name = "PORT",
        num_args = 0..=1,
        require_equals = true,
        default_missing_value = "8765"
    )]
    pub(crate) view: Option<u16>,
    // Placement (`--place`).
    #[command(flatten)]
    pub(crate) placing: PlaceArgs,
}

#[derive(Debug, Args)]
pub(crate) struct ResolveArgs {
    /// The launcher: its file, or its name in the repositories (with
    /// `--repo`, or the repositories file).
    #[arg(value_name = "LAUNCHER")]
    pub(crate) launcher: PathBuf,
    /// A repository to find a launcher named by name in (repeatable).
    #[arg(long = "repo", value_name = "DIR")]
    pub(crate) repos: Vec<PathBuf>,
    /// Choose options of a composed launcher's axes: `option` or
    /// `axis=option`, comma-separated, repeatable (`--with mujoco,cameras=sim_cameras`).
    #[arg(long = "with", value_name = "OPTIONS")]
    pub(crate) with: Vec<String>,
    /// Print every selection the launcher's axes allow, one per line as
    /// `--with` words, and which constraint refuses each refused one.
    #[arg(long, conflicts_with = "with")]
    pub(crate) list: bool,
}

#[derive(Debug, Args)]
pub(crate) struct GraphArgs {
    /// The launcher: its file, or its name in the repositories (with
    /// `--live`: the stack started from it; give none to look at the only
    /// running launch).
    #[arg(value_name = "LAUNCHER", required_unless_present = "live")]
    pub(crate) file: Option<PathBuf>,
    /// Choose options of a composed launcher's axes: `option` or
    /// `axis=option`, comma-separated, repeatable (`--with mujoco,cameras=sim_cameras`).
    #[arg(long = "with", value_name = "OPTIONS")]
    pub(crate) with: Vec<String>,
    /// Draw the running stack instead: the instances that answer and the
    /// message flows measured while sampling.
    #[arg(long)]
    pub(crate) live: bool,
    /// With `--live`: seconds to measure message rates for.
    #[arg(long, value_name = "SECONDS", default_value = "2", value_parser = parse_wait)]
    pub(crate) sample: Duration,
    #[command(flatten)]
    pub(crate) stack: StackArgs,
    /// An extra repository directory (repeatable).
    #[arg(long = "repo", value_name = "DIR")]
    pub(crate) repos: Vec<PathBuf>,
    /// Write the picture to FILE instead of DOT on stdout; the extension
    /// picks the format: `.svg`, `.html`/`.htm` (needs no Graphviz), or
    /// `.dot`/`.gv`.
    #[arg(long, short = 'o', value_name = "FILE")]
    pub(crate) output: Option<PathBuf>,
    // Placement (`--place`).
    #[command(flatten)]
    pub(crate) placing: PlaceArgs,
}

#[derive(Debug, Args)]
pub(crate) struct RunArgs {
    /// The node: `name:tag` from the repositories, or a path.
    #[arg(value_name = "NODE")]
    pub(crate) node: String,
    /// The instance id (default: a readable random id).
    #[arg(short = 'i', long, value_name = "ID")]
    pub(crate) instance_id: Option<String>,
    /// Bind a slot: `--bind left_cam@rs_left` (repeatable, or
    /// comma-separated).
    #[arg(long = "bind", value_name = "KEY@INSTANCE", value_delimiter = ',')]
    pub(crate) bind: Vec<String>,
    /// Link a slot, as PeppyOS's `node/v1` links: `--link camera@cam_1`, a
    /// pairing slot to its peer `--link arm@arm_1[/slot]` (repeatable, or
    /// comma-separated: `--link a@p1,b@p2`; repeat a key for a list slot;
    /// every key must name a slot).
    #[arg(long = "link", value_name = "SLOT@TARGET", value_delimiter = ',')]
    pub(crate) link: Vec<String>,
    /// Leave a `zero_or_one` slot empty on purpose: `--vacant-link 'logger=why'`.
    #[arg(long = "vacant-link", value_name = "SLOT=WHY")]
    pub(crate) vacant_link: Vec<String>,
    /// Parameter values, `key=value` (dot-paths for groups).
    #[arg(value_name = "KEY=VALUE")]
    pub(crate) overrides: Vec<String>,
    /// An extra repository directory (repeatable).
    #[arg(long = "repo", value_name = "DIR")]
    pub(crate) repos: Vec<PathBuf>,
    /// Add the instance to a running launch (its pid, namespace, launcher
    /// path or launcher name; `-` for the only one running): built here,
    /// its links checked against the instances the launch runs, then
    /// started and supervised by the launch as one of its own (`ps`,
    /// `node stop`, `stop` reach it). The command returns once it runs.
    #[arg(long, value_name = "LAUNCH", conflicts_with = "connect")]
    pub(crate) join: Option<String>,
    /// The namespace to join (default: `default`).
    #[arg(long, value_name = "NS")]
    pub(crate) namespace: Option<String>,
    /// Endpoints to connect to (e.g. a launch's router).
    #[arg(long, value_name = "ENDPOINT")]
    pub(crate) connect: Vec<String>,
    /// Endpoints for the node to listen on.
    #[arg(long, value_name = "ENDPOINT")]
    pub(crate) listen: Vec<String>,
    /// Skip the node's build command.
    #[arg(long)]
    pub(crate) no_build: bool,
    /// Follow simulated time: the node's clock gives the latest sim tick
    /// published in its namespace (`peppy/<ns>/clock/tick/sim`).
    #[arg(long)]
    pub(crate) use_sim_time: bool,
    /// Seconds between SIGINT and SIGTERM when stopping; never less than a
    /// node's shutdown-hook window plus 2 s (7 s for the default window).
    #[arg(long, value_name = "SECONDS", default_value = "5", value_parser = parse_grace)]
    pub(crate) grace: Duration,
}

/// Placement and finding launchers: where a launcher's core nodes run
/// (`--place`), shared by `up`, `check`, `graph` and `keys`. A LAUNCHER
/// argument that is no path is a launcher's name, looked up in the
/// repositories (`peppy_repository.json5`'s `launchers`, or their files).
#[derive(Debug, Clone, Default, Args)]
pub(crate) struct PlaceArgs {
    /// Run the launcher's core node (placeholder) LINK on the machine
    /// CORE_NODE, which then names its instances' keys (repeatable; every
    /// core node placed exactly once; several may share a machine).
    /// `LINK@self` is this machine: `up --core-node NAME`, else its host
    /// name. `up` starts what is placed on this machine.
    #[arg(long = "place", value_name = "LINK@CORE_NODE")]
    pub(crate) place: Vec<String>,
}

/// The longest grace period accepted: the longest shutdown window a node
/// may have (`peppy_schema::MAX_SHUTDOWN_GRACE_SECS`), so `--grace` can
/// always cover a window set in a node's code.
const MAX_GRACE_SECONDS: f64 = peppy_schema::MAX_SHUTDOWN_GRACE_SECS;

/// A number of seconds on the command line that clap refuses.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub(crate) enum SecondsError {
    /// Not a number.
    #[error("`{text}` is not a number of seconds")]
    NotANumber {
        /// The value given.
        text: String,
    },
    /// A number outside the option's range (or not finite).
    #[error("`{text}` is out of range: give seconds from {min} to {max}")]
    OutOfRange {
        /// The value given.
        text: String,
        /// The least accepted.
        min: f64,
        /// The most accepted.
        max: f64,
    },
}

/// Seconds from `min` to `max` (finite).
fn parse_seconds(s: &str, min: f64, max: f64) -> Result<Duration, SecondsError> {
    let seconds: f64 = s.trim().parse().map_err(|_| SecondsError::NotANumber {
        text: s.to_string(),
    })?;
    if !seconds.is_finite() || !(min..=max).contains(&seconds) {
        return Err(SecondsError::OutOfRange {
            text: s.to_string(),
            min,
            max,
        });
    }
    Ok(Duration::from_secs_f64(seconds))
}

/// A wait: a finite, positive number of seconds up to a day.
fn parse_wait(s: &str) -> Result<Duration, SecondsError> {
    parse_seconds(s, 0.001, 86400.0)
}

/// `record --duration`: a positive number of seconds up to a year.
fn parse_duration(s: &str) -> Result<Duration, SecondsError> {
    parse_seconds(s, 0.001, MAX_GRACE_SECONDS)
}

/// `replay --start/--end`: seconds into a recording, from 0.
fn parse_offset(s: &str) -> Result<Duration, SecondsError> {
    parse_seconds(s, 0.0, MAX_GRACE_SECONDS)
}

/// A size clap refuses.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("`{0}` is not a size: give bytes, or a number with K, M or G (powers of 1024), e.g. 500M")]
pub(crate) struct SizeError(String);

/// `--max-size`: bytes, or a number with a K/M/G suffix (`KiB`, `MB`
/// read the same: powers of 1024).
fn parse_size(s: &str) -> Result<u64, SizeError> {
    let text = s.trim();
    let split = text
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(text.len());
    let (number, unit) = text.split_at(split);
    let scale: u64 = match unit.trim().to_ascii_uppercase().as_str() {
        "" | "B" => 1,
        "K" | "KB" | "KIB" => 1 << 10,
        "M" | "MB" | "MIB" => 1 << 20,
        "G" | "GB" | "GIB" => 1 << 30,
        "T" | "TB" | "TIB" => 1 << 40,
        _ => return Err(SizeError(s.to_string())),
    };
    let value: f64 = number.parse().map_err(|_| SizeError(s.to_string()))?;
    let bytes = value * scale as f64;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(SizeError(s.to_string()));
    }
    Ok(bytes as u64)
}

/// `--grace`: a finite number of seconds from 0 to a year.
fn parse_grace(s: &str) -> Result<Duration, SecondsError> {
    parse_seconds(s, 0.0, MAX_GRACE_SECONDS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_take_units() {
        assert_eq!(parse_size("1048576"), Ok(1 << 20));
        assert_eq!(parse_size("500M"), Ok(500 << 20));
        assert_eq!(parse_size("1.5GiB"), Ok(3 << 29));
        assert_eq!(parse_size("2 kb"), Ok(2048));
        for bad in ["", "M", "-1M", "0", "1X", "1e3", "NaN"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn grace_takes_finite_seconds_in_range() {
        assert_eq!(parse_grace("1.5"), Ok(Duration::from_millis(1500)));
        assert_eq!(parse_grace("0"), Ok(Duration::ZERO));
        for bad in ["-1", "NaN", "inf", "-inf", "1e300", "soon", ""] {
            assert!(parse_grace(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_grace("7202"), Ok(Duration::from_secs(7202)));
        assert_eq!(
            parse_grace("31536001").unwrap_err().to_string(),
            "`31536001` is out of range: give seconds from 0 to 31536000"
        );
        assert_eq!(
            parse_grace("soon").unwrap_err(),
            SecondsError::NotANumber {
                text: "soon".into()
            }
        );
    }

    #[test]
    fn waits_take_a_millisecond_to_a_day() {
        assert_eq!(parse_wait("0.5"), Ok(Duration::from_millis(500)));
        assert_eq!(parse_wait("0.001"), Ok(Duration::from_millis(1)));
        for bad in ["0", "1e-10", "-1", "NaN", "inf", "86401", "soon"] {
            assert!(parse_wait(bad).is_err(), "{bad}");
        }
        assert_eq!(
            parse_wait("0").unwrap_err().to_string(),
            "`0` is out of range: give seconds from 0.001 to 86400"
        );
    }
}
