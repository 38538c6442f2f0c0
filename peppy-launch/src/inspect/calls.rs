//! `service list/call` and `action list/send-goal`.

use peppy_runtime::Outcome;
use peppy_runtime::describe::InstanceInfo;
use peppy_runtime::tool::Raw;
use peppy_schema::MessageFormat;
use serde_json::json;

use super::dynamic;
use super::nodes::table;
use super::topics::encode_arg;
use super::{Observer, SelectError, owner_label, print_json};
use crate::cli::{CallArgs, Format, GoalArgs, ListArgs};
use crate::error::{InspectError, LaunchError, Result};

fn served<'a, T>(
    info: &'a InstanceInfo,
    items: &'a [T],
    name: &str,
    kind: &'static str,
    name_of: impl Fn(&T) -> &str,
) -> Result<&'a T> {
    items.iter().find(|x| name_of(x) == name).ok_or_else(|| {
        SelectError::NotServed {
            instance: info.instance_id.clone(),
            kind,
            name: name.to_string(),
            served: items.iter().map(|x| name_of(x).to_string()).collect(),
        }
        .into()
    })
}

/// Decodes a body with a described format, for printing.
fn decoded(canonical: &str, body: &[u8], what: &'static str) -> Result<dynamic::Dyn> {
    let format =
        MessageFormat::from_canonical(canonical).map_err(InspectError::UnreadableFormat)?;
    dynamic::decode(&format, body)
        .map_err(|source| InspectError::Undecodable { what, source }.into())
}

fn show(format: Format, label: &str, value: &dynamic::Dyn) {
    match format {
        Format::Json => print_json(&json!({ label: dynamic::to_json(value) })),
        Format::Human => {
            println!("{label}:");
            for line in dynamic::to_text(value).lines() {
                println!("  {line}");
            }
        }
    }
}

/// Prints served entries as a table, or as JSON objects keyed by `keys`.
fn print_entries(
    format: Format,
    none: &str,
    header: &[&str],
    keys: &[&str],
    rows: Vec<Vec<String>>,
) {
    if format == Format::Json {
        let list: Vec<serde_json::Value> = rows
            .into_iter()
            .map(|row| {
                keys.iter()
                    .zip(row)
                    .map(|(k, v)| (k.to_string(), serde_json::Value::String(v)))
                    .collect::<serde_json::Map<_, _>>()
                    .into()
            })
            .collect();
        print_json(&serde_json::Value::Array(list));
    } else if rows.is_empty() {
        println!("{none}");
    } else {
        print!("{}", table(header, &rows));
    }
}

pub(crate) async fn list_services(args: ListArgs) -> Result {
    let observer = Observer::open(&args.stack).await?;
    let all = observer.describe_all().await?;
    let rows = all
        .values()
        .flat_map(|i| {
            i.services.iter().map(|s| {
                vec![
                    i.instance_id.clone(),
                    s.name.clone(),
                    owner_label(&s.owner),
                    s.request.canonical.clone(),
                    s.response.canonical.clone(),
                ]
            })
        })
        .collect();
    print_entries(
        args.format,
        &format!("no instance serves a service in {}", observer.reach.what),
        &["INSTANCE", "SERVICE", "OWNER", "REQUEST", "RESPONSE"],
        &["instance", "service", "owner", "request", "response"],
        rows,
    );
    Ok(())
}

pub(crate) async fn call(args: CallArgs) -> Result {
    let observer = Observer::open(&args.stack).await?;
    let info = observer.describe_one(&args.instance).await?;
    let service = served(&info, &info.services, &args.service, "service", |s| &s.name)?;
    let request = encode_arg(&service.request.canonical, "request", args.value.as_deref())?;
    let body = observer
        .caller()
        .call(service, &info.instance_id, request, args.timeout)
        .await
        .map_err(InspectError::Call)?;
    let response = decoded(&service.response.canonical, &body, "response")?;
    show(args.format, "response", &response);
    Ok(())
}

pub(crate) async fn list_actions(args: ListArgs) -> Result {
    let observer = Observer::open(&args.stack).await?;
    let all = observer.describe_all().await?;
    let rows = all
        .values()
        .flat_map(|i| {
            i.actions.iter().map(|a| {
                vec![
                    i.instance_id.clone(),
                    a.name.clone(),
                    owner_label(&a.owner),
                    a.goal.canonical.clone(),
                    a.feedback.canonical.clone(),
                    a.result.canonical.clone(),
                ]
            })
        })
        .collect();
    print_entries(
        args.format,
        &format!("no instance serves an action in {}", observer.reach.what),
        &["INSTANCE", "ACTION", "OWNER", "GOAL", "FEEDBACK", "RESULT"],
        &["instance", "action", "owner", "goal", "feedback", "result"],
        rows,
    );
    Ok(())
}

pub(crate) async fn send_goal(args: GoalArgs) -> Result {
    let observer = Observer::open(&args.stack).await?;
    let info = observer.describe_one(&args.instance).await?;
    let action = served(&info, &info.actions, &args.action, "action", |a| &a.name)?;
    let goal = encode_arg(&action.goal.canonical, "goal", args.value.as_deref())?;
    let caller = observer.caller();
    let stop = super::interrupted();
    if stop.is_cancelled() {
        return Err(LaunchError::Interrupted);
    }
    let deadline = tokio::time::Instant::now() + args.timeout;
    let mut client = caller
        .send_goal(action, &info.instance_id, goal, args.timeout)
        .await
        .map_err(InspectError::Call)?;
    if !client.accepted {
        return Err(InspectError::Rejected {
            instance: info.instance_id.clone(),
            reason: client.error_message.clone(),
        }
        .into());
    }
    if args.format == Format::Human {
        println!("goal {} accepted by {}", client.goal_id(), info.instance_id);
    }
    let mut cancelled = false;
    if action.feedback.fingerprint != 0 {
        loop {
            tokio::select! {
                f = client.next_feedback::<Raw>() => match f {
                    Ok(Raw(body)) => match decoded(&action.feedback.canonical, &body, "feedback") {
                        Ok(v) => show(args.format, "feedback", &v),
                        Err(e) => eprintln!("note: {e}"),
                    },
                    Err(_) => break,
                },
                () = stop.cancelled() => {
                    cancel(&client, "interrupted").await;
                    cancelled = true;
                    break;
                }
                () = tokio::time::sleep_until(deadline) => break,
            }
        }
    }
    let left = deadline.saturating_duration_since(tokio::time::Instant::now());
    if !cancelled && left.is_zero() {
        // Do not leave the arm moving for a caller that gave up.
        cancel(&client, "no result within --timeout").await;
        cancelled = true;
    }
    let outcome = if cancelled {
        client.result::<Raw>(CANCEL_TIMEOUT).await
    } else {
        tokio::select! {
            r = client.result::<Raw>(left) => r,
            () = stop.cancelled() => {
                cancel(&client, "interrupted").await;
                cancelled = true;
                client.result::<Raw>(CANCEL_TIMEOUT).await
            }
        }
    };
    let outcome = match outcome {
        Ok(o) => o,
        Err(e) => {
            if !cancelled {
                cancel(&client, "no result within --timeout").await;
            }
            return Err(InspectError::Call(e).into());
        }
    };
    let (label, body) = match outcome {
        Outcome::Completed(Raw(b)) => ("result", b),
        Outcome::Cancelled(Raw(b)) => ("cancelled with result", b),
        Outcome::Abandoned => return Err(InspectError::Abandoned.into()),
        Outcome::Expired => return Err(InspectError::Expired.into()),
    };
    let value = decoded(&action.result.canonical, &body, "result")?;
    show(args.format, label, &value);
    if label == "result" {
        Ok(())
    } else {
        Err(InspectError::Cancelled {
            goal: client.goal_id().to_string(),
        }
        .into())
    }
}

/// How long a cancel (and the result after it) may take.
const CANCEL_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(5);

/// Asks the server to cancel the goal and says how that went.
async fn cancel(client: &peppy_runtime::tool::GoalClient, why: &str) {
    match client.cancel(CANCEL_TIMEOUT).await {
        Ok(state) => eprintln!("{why}: cancel requested ({state:?})"),
        Err(e) => eprintln!("{why}: the cancel request failed: {e}"),
    }
}
