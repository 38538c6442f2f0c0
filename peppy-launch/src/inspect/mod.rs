//! Looking into a running stack: `node`, `topic`, `service`, `action`,
//! `graph --live`. The observer joins the stack's Zenoh network as a plain
//! peer: it holds no liveliness token and serves nothing, so it never fills
//! a slot and never counts as a producer. What it knows of the stack comes
//! from the instances themselves: each answers its description
//! ([`InstanceInfo`]) with every entry's format text, so messages decode
//! without generated code.

pub(crate) mod calls;
pub(crate) use peppy_wire::dynamic;
pub(crate) mod live_graph;
pub(crate) mod nodes;
pub(crate) mod pairs;
pub(crate) mod rates;
pub(crate) mod stream;
pub(crate) mod topics;

use std::collections::BTreeMap;
use std::future::Future;
use std::sync::OnceLock;
use std::time::Duration;

use peppy_runtime::describe::InstanceInfo;
use peppy_runtime::tool::ToolCaller;
use peppy_runtime::wire::keys::describe_selector;
use tokio_util::sync::CancellationToken;
use zenoh::query::{ConsolidationMode, QueryTarget};

use crate::cli::{ActionCommand, ListArgs, NodeInfoArgs, ServiceCommand, StackArgs, TopicCommand};
use crate::error::{InspectError, LaunchError, Result, SetupError, UsageError};
use crate::runs::{self, LaunchRecord};

/// How long descriptions keep arriving after joining before a round that
/// adds nobody ends the discovery.
const SETTLE: Duration = Duration::from_millis(400);
/// Pause between discovery rounds.
const ROUND_PAUSE: Duration = Duration::from_millis(100);

/// Where `peppy-launch run` nodes meet when no endpoint is given.
pub(crate) const LOCAL_HUB: &str = "tcp/127.0.0.1:7447";

/// `node list`.
pub(crate) fn node_list(args: ListArgs) -> Result {
    block_on_value(nodes::list(args))
}

/// `node info`.
pub(crate) fn node_info(args: NodeInfoArgs) -> Result {
    block_on_value(nodes::info(args))
}

/// `topic ...`.
pub(crate) fn topic(cmd: TopicCommand) -> Result {
    match cmd {
        TopicCommand::List(args) => block_on_value(topics::list(args)),
        TopicCommand::Echo(args) => block_on_stream(topics::echo(args)),
        TopicCommand::Hz(args) => block_on_stream(rates::run(args, rates::Measure::Rate)),
        TopicCommand::Bw(args) => block_on_stream(rates::run(args, rates::Measure::Bandwidth)),
        TopicCommand::Pub(args) => block_on_stream(topics::publish(args)),
    }
}

/// `service ...`.
pub(crate) fn service(cmd: ServiceCommand) -> Result {
    match cmd {
        ServiceCommand::List(args) => block_on_value(calls::list_services(args)),
        ServiceCommand::Call(args) => block_on_value(calls::call(args)),
    }
}

/// `action ...`.
pub(crate) fn action(cmd: ActionCommand) -> Result {
    match cmd {
        ActionCommand::List(args) => block_on_value(calls::list_actions(args)),
        ActionCommand::SendGoal(args) => block_on_stream(calls::send_goal(args)),
    }
}

/// Runs a command that ends itself cleanly on Ctrl-C (a stream stops and
/// reports, a goal is cancelled); it watches [`interrupted`].
pub(crate) fn block_on_stream<F: Future<Output = Result>>(f: F) -> Result {
    runtime()?.block_on(async {
        listen_for_interrupts();
        f.await
    })
}

/// Runs a command that has nothing to finish on Ctrl-C, on a small runtime
/// of its own: Ctrl-C ends it at once (exit 130).
pub(crate) fn block_on_value<T, F: Future<Output = Result<T>>>(f: F) -> Result<T> {
    runtime()?.block_on(async {
        listen_for_interrupts();
        let stop = interrupted();
        tokio::select! {
            r = f => r,
            () = stop.cancelled() => Err(LaunchError::Interrupted),
        }
    })
}

fn runtime() -> Result<tokio::runtime::Runtime> {
    Ok(crate::tokio_runtime(Some(2))?)
}

/// Fires on the first Ctrl-C, so a command notices an interrupt at any
/// point, not only while it waits for the next message.
pub(crate) fn interrupted() -> CancellationToken {
    static TOKEN: OnceLock<CancellationToken> = OnceLock::new();
    TOKEN.get_or_init(CancellationToken::new).clone()
}

/// Turns SIGINT into [`interrupted`] for the running runtime; a second
/// Ctrl-C exits at once.
fn listen_for_interrupts() {
    let token = interrupted();
    tokio::spawn(async move {
        let Ok(mut sigint) =
            tokio::signal::unix::signal(tokio::signal::unix::SignalKind::interrupt())
        else {
            return;
        };
        if sigint.recv().await.is_some() {
            token.cancel();
        }
        if sigint.recv().await.is_some() {
            std::process::exit(i32::from(crate::error::exit::INTERRUPTED));
        }
    });
}

/// What an inspection command names is not in the running stacks: a
/// stack, an instance, an entry, a topic's producer or consumer.
#[derive(Debug, thiserror::Error)]
pub enum SelectError {
    /// `--launcher` names a launcher with no launch running here.
    #[error(
        "no launch of {} is running on this machine; start it with `peppy-launch up {}`, or reach it elsewhere with --connect ENDPOINT",
        launcher.display(),
        launcher.display()
    )]
    NotRunning {
        /// The launcher file.
        launcher: std::path::PathBuf,
    },
    /// Several stacks run and none was chosen.
    #[error(
        "{} stacks are running; pick one with --launcher (or --namespace):\n{}",
        stacks.len(),
        stacks_text(stacks)
    )]
    SeveralStacks {
        /// Each stack's (first) launcher and its namespace.
        stacks: Vec<(std::path::PathBuf, String)>,
    },
    /// No running instance has that id.
    #[error(
        "no instance `{instance}` answers in {stack} (not running, or out of reach); answering: {}",
        answering.join(", ")
    )]
    NoSuchInstance {
        /// The instance asked for.
        instance: String,
        /// The stack, as the command found it.
        stack: String,
        /// The instances that answered.
        answering: Vec<String>,
    },
    /// The instance serves no such service or action.
    #[error(
        "`{instance}` serves no {kind} `{name}`; its {kind}s: {}",
        listed(served)
    )]
    NotServed {
        /// The instance.
        instance: String,
        /// `service` or `action`.
        kind: &'static str,
        /// The name asked for.
        name: String,
        /// What it serves of that kind.
        served: Vec<String>,
    },
    /// A `TOPIC` argument that is no topic.
    #[error(
        "`{arg}` is not a topic: give `NAME`, `OWNER/NAME` with OWNER as `name:tag`, or `node/OWNER/NAME` / `interface/OWNER/NAME`"
    )]
    NotATopic {
        /// The argument.
        arg: String,
    },
    /// No running instance emits or consumes the topic.
    #[error(
        "no running instance emits or consumes topic `{topic}`; topics: {}",
        listed(topics)
    )]
    NoSuchTopic {
        /// The topic asked for.
        topic: String,
        /// Every topic the running instances emit or consume.
        topics: Vec<String>,
    },
    /// A node and an interface of one `name:tag` both emit the topic.
    #[error(
        "`{topic}` is emitted by a node and by an interface of that name; say which: `node/{topic}` or `interface/{topic}`"
    )]
    NodeOrInterface {
        /// The topic asked for.
        topic: String,
    },
    /// Nobody emits the topic, and nothing tells whose it is.
    #[error(
        "no running instance emits `{topic}`; say whose topic it is: `node/{topic}` or `interface/{topic}`"
    )]
    OwnerKindUnknown {
        /// The topic asked for.
        topic: String,
    },
    /// `--from` / `--as` names an instance that does not emit the topic.
    #[error(
        "`{instance}` does not emit `{topic}`; its producers: {}",
        listed(producers)
    )]
    NotAProducer {
        /// The instance given.
        instance: String,
        /// The topic.
        topic: String,
        /// The instances that emit it.
        producers: Vec<String>,
    },
    /// `--slot` names a slot that does not receive the topic.
    #[error(
        "`{slot}` does not receive `{topic}`; slots that do: {}",
        listed(slots)
    )]
    NotReceivedBy {
        /// The slot given (`INSTANCE.SLOT`).
        slot: String,
        /// The topic name.
        topic: String,
        /// The slots that receive it.
        slots: Vec<String>,
    },
    /// `--slot` and `--from` together, and the slot's binding keeps no
    /// message of that producer.
    #[error(
        "`{slot}` never receives from `{from}`: its binding keeps {}",
        stream::filter_text(keeps)
    )]
    FilteredOut {
        /// The slot given (`INSTANCE.SLOT`).
        slot: String,
        /// The producer given.
        from: String,
        /// The slot's routing filter.
        keeps: peppy_schema::RouteFilter,
    },
    /// `--pair` names no pair's topic ([`pairs::PairSelectError`]).
    #[error(transparent)]
    Pair(#[from] pairs::PairSelectError),
    /// `topic pub` without `--as`, and several instances emit the topic.
    #[error(
        "several instances emit `{topic}`: {}; publish as one of them with --as INSTANCE",
        producers.join(", ")
    )]
    SeveralProducers {
        /// The topic.
        topic: String,
        /// The instances that emit it.
        producers: Vec<String>,
    },
    /// `topic pub` of a topic nobody emits or consumes as an external one.
    #[error(
        "no running instance emits `{topic}` or consumes it as an external topic; topics: {}",
        listed(topics)
    )]
    NotPublishable {
        /// The topic asked for.
        topic: String,
        /// Every topic the running instances emit or consume.
        topics: Vec<String>,
    },
}

/// One line per stack: its launcher and namespace.
fn stacks_text(stacks: &[(std::path::PathBuf, String)]) -> String {
    stacks
        .iter()
        .map(|(launcher, ns)| format!("  {}  (namespace {ns})", launcher.display()))
        .collect::<Vec<_>>()
        .join("\n")
}

/// `a, b, c`, or `none`.
fn listed(items: &[String]) -> String {
    if items.is_empty() {
        "none".into()
    } else {
        items.join(", ")
    }
}

/// Why a reply to a describe query is not a description of the instance
/// it came from (the reply is ignored, with a note).
#[derive(Debug, thiserror::Error)]
pub(crate) enum DescriptionError {
    /// The reply is not an [`InstanceInfo`] in JSON.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// The description does not fit the key it was sent on
    /// ([`InstanceInfo::check`]).
    #[error("{0}")]
    Mismatch(String),
}

/// Where a stack is: its namespace and how to reach it.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Reach {
    pub(crate) namespace: String,
    pub(crate) connect: Vec<String>,
    /// How the stack was found, for messages.
    pub(crate) what: String,
    /// The instances its launch started (`instance`, `node`), when it was
    /// found through a launch record.
    pub(crate) expected: Vec<(String, String)>,
    /// The tools' login of a secured stack, from its launch record.
    pub(crate) login: Option<peppy_runtime::Login>,
    /// The read-only login `record` and `view` use in a secured stack.
    pub(crate) recorder_login: Option<peppy_runtime::Login>,
}

/// Decides which stack the command looks at (see [`StackArgs`]).
pub(crate) fn reach(args: &StackArgs, running: &[LaunchRecord]) -> Result<Reach> {
    // `-l NAME`: the launcher of that name in the repositories.
    let mut named = args.clone();
    named.launcher = args
        .launcher
        .as_deref()
        .map(|l| crate::find_launcher::locate(l, &[]))
        .transpose()?;
    let args = &named;
    let canonical = args
        .launcher
        .as_ref()
        .map(|l| std::fs::canonicalize(l).unwrap_or_else(|_| l.clone()));
    if !args.connect.is_empty() {
        let namespace = match (&args.namespace, &args.launcher) {
            (Some(ns), _) => ns.clone(),
            (None, Some(l)) => crate::up::default_namespace(l),
            (None, None) => peppy_runtime::DEFAULT_NAMESPACE.to_string(),
        };
        return Ok(Reach {
            what: format!("namespace {namespace} via {}", args.connect.join(", ")),
            namespace,
            connect: args.connect.clone(),
            expected: Vec::new(),
            login: None,
            recorder_login: None,
        });
    }
    let matching: Vec<&LaunchRecord> = running
        .iter()
        .filter(|r| canonical.as_ref().is_none_or(|l| &r.launcher == l))
        .filter(|r| args.namespace.as_ref().is_none_or(|ns| &r.namespace == ns))
        .collect();
    // Launches sharing a namespace and endpoints are one stack: several
    // `peppy-launch run`s on the local hub, or relaunches of one file.
    let mut stacks: Vec<Vec<&LaunchRecord>> = Vec::new();
    for r in matching {
        match stacks
            .iter_mut()
            .find(|s| s[0].namespace == r.namespace && s[0].connect == r.connect)
        {
            Some(stack) => stack.push(r),
            None => stacks.push(vec![r]),
        }
    }
    match (stacks.as_slice(), &args.launcher) {
        ([one], _) | ([.., one], Some(_)) => Ok(reach_of(one)),
        ([], Some(l)) => Err(SelectError::NotRunning {
            launcher: l.clone(),
        }
        .into()),
        ([], None) => {
            let namespace = args
                .namespace
                .clone()
                .unwrap_or_else(|| peppy_runtime::DEFAULT_NAMESPACE.to_string());
            Ok(Reach {
                what: format!("namespace {namespace} on the local hub {LOCAL_HUB}"),
                namespace,
                connect: vec![LOCAL_HUB.to_string()],
                expected: Vec::new(),
                login: None,
                recorder_login: None,
            })
        }
        (several, None) => Err(SelectError::SeveralStacks {
            stacks: several
                .iter()
                .map(|s| (s[0].launcher.clone(), s[0].namespace.clone()))
                .collect(),
        }
        .into()),
    }
}

/// One stack made of one or more launches.
fn reach_of(launches: &[&LaunchRecord]) -> Reach {
    let first = launches[0];
    let what = match launches {
        [one] => format!(
            "{} (namespace {}, pid {})",
            one.launcher.display(),
            one.namespace,
            one.pid
        ),
        several => format!("namespace {} ({} launches)", first.namespace, several.len()),
    };
    Reach {
        namespace: first.namespace.clone(),
        connect: first.connect.clone(),
        expected: launches
            .iter()
            .flat_map(|r| r.instances.iter().cloned())
            .collect(),
        login: first.login.clone(),
        recorder_login: first.recorder_login.clone(),
        what,
    }
}

/// Whose login an observer presents to a secured stack.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Role {
    /// The launching user's tools: allowed everything in the namespace.
    Operator,
    /// `record` and `view`: allowed to read topics, descriptions and
    /// formats only.
    Recorder,
}

/// A connection to a running stack.
pub(crate) struct Observer {
    pub(crate) session: zenoh::Session,
    pub(crate) reach: Reach,
    wait: Duration,
    noted: std::sync::Mutex<std::collections::HashSet<String>>,
}

impl Observer {
    /// Joins the stack found from `args` as a peer that only connects,
    /// with the login of the launching user's tools.
    pub(crate) async fn open(args: &StackArgs) -> Result<Observer> {
        Observer::open_as(args, Role::Operator).await
    }

    /// [`Observer::open`] with the login of `role`.
    pub(crate) async fn open_as(args: &StackArgs, role: Role) -> Result<Observer> {
        let mut reach = reach(args, &runs::running())?;
        if role == Role::Recorder {
            match (&reach.login, &reach.recorder_login) {
                (_, Some(recorder)) => reach.login = Some(recorder.clone()),
                // A secured launch whose record names no recorder (started
                // by an older peppy-launch) admits its tools' login only.
                (Some(_), None) => eprintln!(
                    "note: this launch keeps no recorder login (restart it to have one); reading it with its tools' login"
                ),
                (None, None) => {}
            }
        }
        // A client talks to the stack's router only: a peer would also open
        // direct links to every node, which they would see (and log) come
        // and go with each command.
        let config = peppy_runtime::Endpoints {
            mode: Some("client".into()),
            listen: Vec::new(),
            connect: reach.connect.clone(),
            multicast_scouting: false,
            login: reach.login.clone(),
        }
        .zenoh_config()
        .map_err(UsageError::Endpoints)?;
        let session = zenoh::open(config)
            .await
            .map_err(|source| InspectError::Unreachable {
                stack: reach.what.clone(),
                local_hub: reach.connect == [LOCAL_HUB],
                with_login: reach.login.is_some(),
                source,
            })?;
        Ok(Observer {
            session,
            reach,
            wait: args.wait,
            noted: Default::default(),
        })
    }

    /// Every running instance's description, by instance id. Replies that
    /// do not parse are dropped with a note (an instance of another peppy
    /// version, or not a peppy node at all).
    ///
    /// A session that just joined learns the stack's queryables over a few
    /// milliseconds, so one query may see only some instances: it asks in
    /// rounds until every instance its launch started has answered (or, for
    /// a stack found without a launch record, a round adds nobody after
    /// [`SETTLE`]), or `--wait` ends.
    pub(crate) async fn describe_all(&self) -> Result<BTreeMap<String, InstanceInfo>> {
        let start = tokio::time::Instant::now();
        let deadline = start + self.wait;
        let mut out = BTreeMap::new();
        loop {
            let before = out.len();
            self.describe_round(&mut out, deadline).await?;
            let now = tokio::time::Instant::now();
            // A launch's own instances are known: wait for all of them;
            // otherwise until a round adds nobody.
            let all_expected = !self.reach.expected.is_empty()
                && self
                    .reach
                    .expected
                    .iter()
                    .all(|(id, _)| out.contains_key(id));
            let settled = all_expected
                || (self.reach.expected.is_empty()
                    && !out.is_empty()
                    && out.len() == before
                    && now >= start + SETTLE);
            if settled || now >= deadline {
                return Ok(out);
            }
            tokio::time::sleep(ROUND_PAUSE.min(deadline - now)).await;
        }
    }

    async fn describe_round(
        &self,
        out: &mut BTreeMap<String, InstanceInfo>,
        deadline: tokio::time::Instant,
    ) -> Result<()> {
        let budget = deadline
            .saturating_duration_since(tokio::time::Instant::now())
            .max(Duration::from_millis(10));
        let replies = self
            .session
            .get(describe_selector(&self.reach.namespace))
            .target(QueryTarget::All)
            .consolidation(ConsolidationMode::None)
            .timeout(budget)
            .await
            .map_err(|source| SetupError::Query {
                stack: self.reach.what.clone(),
                source,
            })?;
        while let Ok(reply) = replies.recv_async().await {
            let Ok(sample) = reply.result() else { continue };
            match self.description(sample) {
                Ok(info) => {
                    out.insert(info.instance_id.clone(), info);
                }
                // Once per instance, not once per discovery round.
                Err(e) if self.first_note(sample.key_expr().as_str()) => eprintln!(
                    "note: ignoring the description on {}: {e}",
                    sample.key_expr()
                ),
                Err(_) => {}
            }
        }
        Ok(())
    }

    /// One instance's description, asked directly (`None` if it does not
    /// answer within `--wait`).
    pub(crate) async fn describe_instance(
        &self,
        core: &str,
        instance: &str,
    ) -> Option<InstanceInfo> {
        let key = peppy_runtime::wire::keys::describe_key(&self.reach.namespace, core, instance);
        let replies = self.session.get(&key).timeout(self.wait).await.ok()?;
        let reply = replies.recv_async().await.ok()?;
        self.description(reply.result().ok()?).ok()
    }

    /// A description read from a reply and checked against where it came
    /// from (`InstanceInfo::check`).
    fn description(
        &self,
        sample: &zenoh::sample::Sample,
    ) -> std::result::Result<InstanceInfo, DescriptionError> {
        let info = InstanceInfo::from_json(&sample.payload().to_bytes())?;
        info.check(&self.reach.namespace, sample.key_expr().as_str())
            .map_err(DescriptionError::Mismatch)?;
        Ok(info)
    }

    /// The descriptions, or an error saying nothing answered.
    pub(crate) async fn describe_some(&self) -> Result<BTreeMap<String, InstanceInfo>> {
        let all = self.describe_all().await?;
        if all.is_empty() {
            return Err(InspectError::NoAnswer {
                stack: self.reach.what.clone(),
                wait: self.wait,
            }
            .into());
        }
        Ok(all)
    }

    /// One instance's description, or an error listing the running ones.
    pub(crate) async fn describe_one(&self, instance: &str) -> Result<InstanceInfo> {
        let mut all = self.describe_some().await?;
        all.remove(instance).ok_or_else(|| {
            SelectError::NoSuchInstance {
                instance: instance.to_string(),
                stack: self.reach.what.clone(),
                answering: all.keys().cloned().collect(),
            }
            .into()
        })
    }

    /// Whether `what` is noted for the first time (notes are said once).
    fn first_note(&self, what: &str) -> bool {
        self.noted
            .lock()
            .map(|mut n| n.insert(what.to_string()))
            .unwrap_or(false)
    }

    /// A caller for service calls and goals, named after this process.
    pub(crate) fn caller(&self) -> ToolCaller {
        ToolCaller::new(
            self.session.clone(),
            "cli",
            &format!("peppy-launch-{}", std::process::id()),
        )
    }
}

/// `name:tag` of an owner, for people.
pub(crate) fn owner_label(owner: &peppy_runtime::describe::OwnerInfo) -> String {
    format!("{}:{}", owner.name, owner.tag)
}

/// Prints `value` as one line of JSON.
pub(crate) fn print_json(value: &serde_json::Value) {
    println!("{value}");
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(launcher: &str, ns: &str) -> LaunchRecord {
        LaunchRecord {
            pid: 1,
            launcher: launcher.into(),
            namespace: ns.into(),
            core_node: "c".into(),
            connect: vec![format!("tcp/127.0.0.1:1{}", ns.len())],
            run_dir: "/tmp".into(),
            started_at_ms: 0,
            instances: Vec::new(),
            login: None,
            recorder_login: None,
            control: None,
        }
    }

    fn args(launcher: Option<&str>, ns: Option<&str>, connect: &[&str]) -> StackArgs {
        StackArgs {
            launcher: launcher.map(Into::into),
            namespace: ns.map(Into::into),
            connect: connect.iter().map(|s| s.to_string()).collect(),
            wait: Duration::from_secs(1),
        }
    }

    #[test]
    fn the_only_running_launch_is_the_default() {
        let r = reach(&args(None, None, &[]), &[record("/a.json5", "a")]).unwrap();
        assert_eq!(r.namespace, "a");
        assert_eq!(r.connect, vec!["tcp/127.0.0.1:11"]);
    }

    #[test]
    fn several_running_launches_need_a_choice() {
        let running = [record("/a.json5", "a"), record("/b.json5", "bb")];
        let e = reach(&args(None, None, &[]), &running)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("2 stacks are running") && e.contains("/b.json5"),
            "{e}"
        );
        let r = reach(&args(None, Some("bb"), &[]), &running).unwrap();
        assert_eq!(r.connect, vec!["tcp/127.0.0.1:12"]);
        let r = reach(&args(Some("/a.json5"), None, &[]), &running).unwrap();
        assert_eq!(r.namespace, "a");
    }

    #[test]
    fn nothing_running_means_the_local_hub_or_an_error_for_a_launcher() {
        let r = reach(&args(None, None, &[]), &[]).unwrap();
        assert_eq!(
            (r.namespace.as_str(), r.connect[0].as_str()),
            ("default", LOCAL_HUB)
        );
        let e = reach(&args(Some("/nowhere.json5"), None, &[]), &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("peppy-launch up /nowhere.json5"), "{e}");
    }

    #[test]
    fn launches_on_one_network_and_namespace_are_one_stack() {
        let mut a = record("/cam.json5", "default");
        a.instances = vec![("cam".into(), "camera:v1".into())];
        let mut b = record("/recon.json5", "default");
        b.instances = vec![("recon".into(), "recon:v1".into())];
        let r = reach(&args(None, None, &[]), &[a, b]).unwrap();
        assert_eq!(r.expected.len(), 2);
        assert!(r.what.contains("2 launches"), "{}", r.what);
    }

    #[test]
    fn connect_reaches_elsewhere() {
        let r = reach(&args(None, Some("lab"), &["tcp/192.0.2.1:7447"]), &[]).unwrap();
        assert_eq!(r.namespace, "lab");
        assert_eq!(r.connect, vec!["tcp/192.0.2.1:7447"]);
    }
}
