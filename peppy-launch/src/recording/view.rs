//! `peppy-launch view`: a running stack served live over the Foxglove
//! WebSocket protocol, in the encoding `record` writes, so a stack and a
//! recording of it look the same in Foxglove.
//!
//! Every producer's topic is a channel (`/<instance>/<topic>`, JSON with
//! its format's JSON Schema, peppy's metadata attached). A message shaped
//! like an image (root `width`, `height`, `encoding` and one byte field) is
//! also published as a `foxglove.RawImage` on `/<instance>/<topic>/image`,
//! so a camera shows as a picture. Every service the stack serves when the
//! view starts can be called from Foxglove, with JSON requests.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use foxglove::messages::{RawImage, Timestamp};
use foxglove::websocket::Capability;
use foxglove::websocket::service::{Service, ServiceSchema};
use foxglove::{ChannelBuilder, Context, RawChannel, Schema, WebSocketServer};
use peppy_runtime::describe::{InstanceInfo, ServedService};
use peppy_runtime::tool::ToolCaller;
use peppy_schema::{FieldType, MessageFormat, Primitive};

use super::{
    ChannelMeta, Learner, MESSAGE_ENCODING, Patterns, SCHEMA_ENCODING, Sampled, subscribe_topics,
};
use crate::cli::ViewArgs;
use crate::error::Result;
use crate::inspect::dynamic::{self, Dyn, JsonForm};
use crate::inspect::{Observer, Role, interrupted};

/// Samples waiting to be decoded beyond which new ones are dropped (and
/// counted): a view never holds the stack back.
const BACKLOG: usize = 1024;
/// How often the view looks for instances that started after it, to offer
/// their services.
const DISCOVERY_PERIOD: Duration = Duration::from_secs(5);
/// How long a service called from Foxglove may take.
const CALL_TIMEOUT: Duration = Duration::from_secs(10);

/// Why `view` could not serve.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    /// The WebSocket server did not start (the port is taken, ...).
    #[error("cannot serve the Foxglove WebSocket protocol on {host}:{port}: {source}")]
    Serve {
        /// The host given.
        host: String,
        /// The port given.
        port: u16,
        /// Why.
        source: foxglove::FoxgloveError,
    },
    /// `--host` is not loopback, and the stack is secured.
    #[error(
        "the stack is secured and the Foxglove protocol has no login: serve it on loopback (127.0.0.1), not `{host}`, and reach it through an SSH tunnel"
    )]
    Exposed {
        /// The host given.
        host: String,
    },
}

/// What a format's messages give an image.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ImageLayout {
    /// The root field holding the pixels.
    pixels: String,
}

/// An image layout when `format` looks like an image: root `width` and
/// `height` (integers), `encoding` (a string) and exactly one byte field.
pub(crate) fn image_layout(format: &MessageFormat) -> Option<ImageLayout> {
    let root = |name: &str| format.fields.iter().find(|f| f.name == name && !f.optional);
    let integer = |name: &str| {
        root(name)
            .is_some_and(|f| matches!(f.ty, FieldType::Primitive(p) if p.int_range().is_some()))
    };
    let text = root("encoding").is_some_and(|f| f.ty == FieldType::Primitive(Primitive::String));
    let bytes: Vec<&str> = format
        .fields
        .iter()
        .filter(|f| !f.optional && is_bytes(&f.ty))
        .map(|f| f.name.as_str())
        .collect();
    match bytes.as_slice() {
        [pixels] if integer("width") && integer("height") && text => Some(ImageLayout {
            pixels: pixels.to_string(),
        }),
        _ => None,
    }
}

fn is_bytes(ty: &FieldType) -> bool {
    match ty {
        FieldType::Primitive(Primitive::Bytes) => true,
        FieldType::Array { items, .. } => **items == FieldType::Primitive(Primitive::U8),
        _ => false,
    }
}

/// Bytes per pixel of an image encoding Foxglove knows.
fn pixel_size(encoding: &str) -> Option<u32> {
    Some(match encoding {
        "mono8" | "8UC1" | "bayer_rggb8" | "bayer_bggr8" | "bayer_gbrg8" | "bayer_grbg8" => 1,
        "mono16" | "16UC1" | "uyvy" | "yuyv" | "yuv422" | "yuv422_yuy2" => 2,
        "rgb8" | "bgr8" | "8UC3" => 3,
        "rgba8" | "bgra8" | "32FC1" => 4,
        _ => return None,
    })
}

/// The message as a `foxglove.RawImage`: its stamp is a root `time` field,
/// or `header.stamp`; its frame id a root or header `frame_id`.
pub(crate) fn to_image(value: &Dyn, layout: &ImageLayout) -> Option<RawImage> {
    let Dyn::Object(fields) = value else {
        return None;
    };
    let get = |name: &str| fields.iter().find(|(n, _)| n == name).map(|(_, v)| v);
    let uint = |name: &str| match get(name) {
        Some(Dyn::UInt(n)) => u32::try_from(*n).ok(),
        Some(Dyn::Int(n)) => u32::try_from(*n).ok(),
        _ => None,
    };
    let (width, height) = (uint("width")?, uint("height")?);
    let Some(Dyn::Str(encoding)) = get("encoding") else {
        return None;
    };
    let Some(Dyn::Bytes(data)) = get(&layout.pixels) else {
        return None;
    };
    let header = match get("header") {
        Some(Dyn::Object(h)) => h.as_slice(),
        _ => &[],
    };
    let in_header = |name: &str| header.iter().find(|(n, _)| n == name).map(|(_, v)| v);
    let stamp = fields
        .iter()
        .find(|(_, v)| matches!(v, Dyn::Time { .. }))
        .map(|(_, v)| v)
        .or_else(|| in_header("stamp"));
    let timestamp = match stamp {
        Some(Dyn::Time { secs, nanos }) => u32::try_from(*secs)
            .ok()
            .and_then(|s| Timestamp::new_checked(s, *nanos)),
        _ => None,
    };
    let frame_id = match get("frame_id").or_else(|| in_header("frame_id")) {
        Some(Dyn::Str(s)) => s.clone(),
        Some(Dyn::UInt(n)) => n.to_string(),
        Some(Dyn::Int(n)) => n.to_string(),
        _ => String::new(),
    };
    let step = match pixel_size(encoding) {
        Some(size) => width.saturating_mul(size),
        None => u32::try_from(data.len() / height.max(1) as usize).unwrap_or(0),
    };
    Some(RawImage {
        timestamp,
        frame_id,
        width,
        height,
        encoding: encoding.clone(),
        step,
        data: data.clone().into(),
    })
}

/// One producer's topic in one format, as the view serves it.
struct Served {
    format: MessageFormat,
    json: Arc<RawChannel>,
    image: Option<(ImageLayout, foxglove::Channel<RawImage>)>,
}

/// `view`.
pub(crate) async fn run(args: ViewArgs) -> Result {
    let patterns = Patterns::new(args.topics.clone());
    let observer = Arc::new(Observer::open_as(&args.stack, Role::Recorder).await?);
    // A secured stack admits only its logins; the protocol has none, so
    // its view stays on this machine.
    let secured = observer.reach.login.is_some();
    if secured && !is_loopback(&args.host) {
        return Err(ViewError::Exposed {
            host: args.host.clone(),
        }
        .into());
    }
    let described = observer.describe_all().await?;
    let context = Context::new();
    let mut offered = BTreeSet::new();
    let services = if secured {
        eprintln!(
            "note: services are not offered to Foxglove: the view's login in a secured stack may not call them"
        );
        Vec::new()
    } else {
        services(&observer, &described, &mut offered)
    };
    let server = WebSocketServer::new()
        .name(format!("peppy {}", observer.reach.namespace))
        .bind(args.host.clone(), args.port)
        .context(&context)
        .capabilities([Capability::Services])
        .supported_encodings([MESSAGE_ENCODING])
        .services(services)
        .start()
        .await
        .map_err(|source| ViewError::Serve {
            host: args.host.clone(),
            port: args.port,
            source,
        })?;
    eprintln!(
        "serving {} to Foxglove on ws://{}:{} ({} services callable); in Foxglove: Open connection, Foxglove WebSocket, that address. Ctrl-C ends it",
        observer.reach.what,
        args.host,
        server.port(),
        offered.len()
    );
    let server = Arc::new(server);
    // Instances that start later (all of them, under `up --view`) have
    // their services offered as they appear.
    let discovery = (!secured).then(|| {
        tokio::spawn(offer_new_services(
            observer.clone(),
            server.clone(),
            offered,
        ))
    });

    let (tx, rx) = flume::bounded::<Sampled>(BACKLOG);
    let dropped = Arc::new(AtomicU64::new(0));
    let subscriber = {
        let dropped = dropped.clone();
        subscribe_topics(&observer, move |sample| {
            if tx.try_send(Sampled::of(&sample)).is_err() {
                dropped.fetch_add(1, Ordering::Relaxed);
            }
        })
        .await?
    };
    let mut learner = Learner::new(described);
    let mut served: HashMap<(String, u64), Option<Served>> = HashMap::new();
    let mut topics: BTreeMap<String, u64> = BTreeMap::new();
    let stop = interrupted();
    let mut json = Vec::new();
    loop {
        let sample = tokio::select! {
            s = rx.recv_async() => match s { Ok(s) => s, Err(_) => break },
            () = stop.cancelled() => break,
        };
        let Some(sender) = peppy_runtime::wire::keys::split_entry_key(&sample.key) else {
            continue;
        };
        if !patterns.takes(sender.instance, sender.entry) {
            continue;
        }
        let Some(fingerprint) = sample.fingerprint else {
            continue;
        };
        let key = (sample.key.clone(), fingerprint);
        if !served.contains_key(&key) {
            let channel = match learner.learn(&observer, &sample.key, fingerprint).await {
                Some((meta, format)) => open_channel(&context, &meta, format, &mut topics),
                None => {
                    eprintln!(
                        "note: not serving {}: format {fingerprint:016x} is described by nobody",
                        sample.key
                    );
                    None
                }
            };
            served.insert(key.clone(), channel);
        }
        let Some(Some(channel)) = served.get(&key) else {
            continue;
        };
        let images = channel
            .image
            .as_ref()
            .filter(|(_, images)| images.has_sinks());
        // Nothing is decoded for a channel no viewer subscribed to.
        if !channel.json.has_sinks() && images.is_none() {
            continue;
        }
        let Ok(value) = dynamic::decode(&channel.format, &sample.payload) else {
            continue;
        };
        let meta = foxglove::PartialMetadata::with_log_time(sample.log_time);
        if channel.json.has_sinks() {
            json.clear();
            dynamic::write_recording_json(&value, &mut json);
            channel.json.log_with_meta(&json, meta);
        }
        if let Some((layout, images)) = images
            && let Some(image) = to_image(&value, layout)
        {
            images.log_with_meta(&image, meta);
        }
    }
    drop(subscriber);
    let lost = dropped.load(Ordering::Relaxed);
    if lost > 0 {
        eprintln!("note: {lost} messages were not shown because the view fell behind the stack");
    }
    if let Some(discovery) = discovery {
        discovery.abort();
        let _ = discovery.await;
    }
    if let Ok(server) = Arc::try_unwrap(server) {
        server.stop().wait().await;
    }
    Ok(())
}

/// Whether `host` is this machine only.
fn is_loopback(host: &str) -> bool {
    host == "localhost"
        || host
            .parse::<std::net::IpAddr>()
            .is_ok_and(|ip| ip.is_loopback())
}

/// Offers the services of instances described after the view started,
/// every few seconds, until the view ends.
async fn offer_new_services(
    observer: Arc<Observer>,
    server: Arc<foxglove::WebSocketServerHandle>,
    mut offered: BTreeSet<(String, String)>,
) {
    loop {
        tokio::time::sleep(DISCOVERY_PERIOD).await;
        let Ok(described) = observer.describe_all().await else {
            continue;
        };
        let new = services(&observer, &described, &mut offered);
        if !new.is_empty()
            && let Err(e) = server.add_services(new)
        {
            eprintln!("note: services not offered to Foxglove: {e}");
        }
    }
}

/// The channels of one producer's topic in one format: JSON, and an image
/// for an image-like format. A format change keeps the topic, suffixed with
/// the new fingerprint.
fn open_channel(
    context: &Arc<Context>,
    meta: &ChannelMeta,
    format: MessageFormat,
    topics: &mut BTreeMap<String, u64>,
) -> Option<Served> {
    let mut topic = meta.channel_topic();
    match topics.get(&topic) {
        Some(fp) if *fp != meta.fingerprint => {
            topic = format!("{topic}@{:016x}", meta.fingerprint);
        }
        _ => {}
    }
    topics.insert(topic.clone(), meta.fingerprint);
    let (title, schema) = meta.schema(&format);
    let json = ChannelBuilder::new(topic.clone())
        .context(context)
        .message_encoding(MESSAGE_ENCODING)
        .schema(Schema::new(title, SCHEMA_ENCODING, schema.into_bytes()))
        .metadata(meta.to_map())
        .build_raw();
    let json = match json {
        Ok(channel) => channel,
        Err(e) => {
            eprintln!("note: not serving {topic}: {e}");
            return None;
        }
    };
    let image = image_layout(&format).map(|layout| {
        let images = ChannelBuilder::new(format!("{topic}/image"))
            .context(context)
            .metadata(meta.to_map())
            .build::<RawImage>();
        (layout, images)
    });
    Some(Served {
        format,
        json,
        image,
    })
}

/// Every service the described instances serve that is not `offered`
/// yet, callable with JSON; each is added to `offered`.
fn services(
    observer: &Observer,
    described: &BTreeMap<String, InstanceInfo>,
    offered: &mut BTreeSet<(String, String)>,
) -> Vec<Service> {
    let mut out = Vec::new();
    for info in described.values() {
        for service in &info.services {
            if !offered.insert((info.instance_id.clone(), service.name.clone())) {
                continue;
            }
            match callable(observer, &info.instance_id, service) {
                Some(s) => out.push(s),
                None => eprintln!(
                    "note: `{}`'s service `{}` is not offered to Foxglove: its formats do not read",
                    info.instance_id, service.name
                ),
            }
        }
    }
    out
}

fn callable(observer: &Observer, instance: &str, service: &ServedService) -> Option<Service> {
    let request = MessageFormat::from_canonical(&service.request.canonical).ok()?;
    let response = MessageFormat::from_canonical(&service.response.canonical).ok()?;
    let name = format!("/{instance}/{}", service.name);
    let title = |part: &str| {
        format!(
            "{}:{}/{}/{part}",
            service.owner.name, service.owner.tag, service.name
        )
    };
    let schema = |format: &MessageFormat, part: &str, fingerprint: u64| {
        Schema::new(
            title(part),
            SCHEMA_ENCODING,
            super::schema::json_schema(format, &title(part), fingerprint)
                .to_string()
                .into_bytes(),
        )
    };
    let service_schema = ServiceSchema::new(title("service"))
        .with_request(
            MESSAGE_ENCODING,
            schema(&request, "request", service.request.fingerprint),
        )
        .with_response(
            MESSAGE_ENCODING,
            schema(&response, "response", service.response.fingerprint),
        );
    let caller = ToolCaller::new(
        observer.session.clone(),
        "cli",
        &format!("peppy-view-{}", std::process::id()),
    );
    let (served, instance) = (Arc::new(service.clone()), instance.to_string());
    let (request, response) = (Arc::new(request), Arc::new(response));
    Some(
        Service::builder(name, service_schema).async_handler_fn(move |call| {
            let (caller, served, instance) = (caller.clone(), served.clone(), instance.clone());
            let (request, response) = (request.clone(), response.clone());
            let payload = call.payload().to_vec();
            async move {
                let json: serde_json::Value = serde_json::from_slice(&payload)
                    .map_err(|e| format!("the request is not JSON: {e}"))?;
                let body = dynamic::encode_as(&request, &json, JsonForm::Recording)
                    .map_err(|e| format!("the request does not fit its format: {e}"))?;
                let answer = caller
                    .call(&served, &instance, body, CALL_TIMEOUT)
                    .await
                    .map_err(|e| e.to_string())?;
                let value = dynamic::decode(&response, &answer)
                    .map_err(|e| format!("the response does not decode: {e}"))?;
                Ok::<_, String>(dynamic::to_recording_json(&value).to_string().into_bytes())
            }
        }),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn format(text: &str) -> MessageFormat {
        MessageFormat::from_canonical(text).unwrap()
    }

    #[test]
    fn camera_frames_are_images() {
        let camera = format(
            "{header:{stamp:time,frame_id:u32},encoding:string,width:u32,height:u32,frame:[u8]}",
        );
        let layout = image_layout(&camera).unwrap();
        let value = Dyn::Object(vec![
            (
                "header".into(),
                Dyn::Object(vec![
                    ("stamp".into(), Dyn::Time { secs: 7, nanos: 9 }),
                    ("frame_id".into(), Dyn::UInt(42)),
                ]),
            ),
            ("encoding".into(), Dyn::Str("mono8".into())),
            ("width".into(), Dyn::UInt(2)),
            ("height".into(), Dyn::UInt(3)),
            ("frame".into(), Dyn::Bytes(vec![1, 2, 3, 4, 5, 6])),
        ]);
        let image = to_image(&value, &layout).unwrap();
        assert_eq!((image.width, image.height, image.step), (2, 3, 2));
        assert_eq!(image.frame_id, "42");
        assert_eq!(image.timestamp, Some(Timestamp::new(7, 9)));
        assert_eq!(&image.data[..], &[1, 2, 3, 4, 5, 6]);

        for not_an_image in [
            "{width:u32,height:u32,frame:[u8]}",
            "{width:u32,height:u32,encoding:string,a:bytes,b:[u8]}",
            "{width:f32,height:u32,encoding:string,frame:bytes}",
            "{width:u32,height:u32,encoding:string,frame:bytes?}",
        ] {
            assert_eq!(image_layout(&format(not_an_image)), None, "{not_an_image}");
        }
    }
}
