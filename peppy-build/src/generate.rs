//! The generator: a resolved node in, the items of its `peppygen` module
//! out. Pure: no file system, no environment.

use peppy_schema::layout::{CategoryLayout, ModuleNode, ModuleRole};
use peppy_schema::{
    Cardinality, Declared, Diagnostics, EntryKind, Loc, MessageFormat, NodeApi, Origin, Provided,
    QosProfile, ResolvedCall, ResolvedNode, ResolvedTopic, ServiceDecl, TopicDecl,
};
use proc_macro2::{Ident, TokenStream};
use quote::quote;

use crate::naming::{Names, ident, short_location, type_prefix};
use crate::params;
use crate::testing::{Layout, TestGate};
use crate::types::{Structs, args, format_spec, many_args_allow, snake_allow};

/// Generates the items of a node's `peppygen` module: the module tree of
/// SPEC 4 (`emitted_topics`, `consumed_topics`, `exposed_services`,
/// `consumed_services`, `exposed_actions`, `consumed_actions`,
/// `parameters`) and the root re-exports.
///
/// The node document's path (`node.node.file`) should be absolute: the
/// generated code embeds the document with `include_str!`.
///
/// Errors are names the generated Rust cannot hold: two entries that map to
/// one module name, or two nested structs with one type name. Each is a
/// located diagnostic, like the schema's own.
pub fn generate(node: &ResolvedNode) -> Result<TokenStream, Diagnostics> {
    generate_as(node, None, TestGate::CfgTest)
}

/// [`generate`], naming the document `document_path` in the generated
/// descriptor instead of its path on this machine: the `.peppy/libs`
/// crate of a node names it relative to the node, so the crate is the same
/// wherever the node is checked out.
pub(crate) fn generate_as(
    node: &ResolvedNode,
    document_path: Option<&str>,
    gate: TestGate,
) -> Result<TokenStream, Diagnostics> {
    let mut g = Gen {
        node,
        document_path: document_path.map(str::to_string),
        diags: Diagnostics::new(),
        gate,
    };
    let tokens = g.tree();
    if g.diags.has_errors() {
        Err(g.diags)
    } else {
        Ok(tokens)
    }
}

/// Items that stand in for the generated ones when the document has
/// errors: the top-level modules and the re-exports, so that user code
/// naming them does not add unresolved-name errors to the real one.
pub fn stub() -> TokenStream {
    let modules = CATEGORIES.iter().map(|(name, _)| {
        let id = ident(name);
        quote!(pub mod #id {})
    });
    quote! {
        pub use ::peppy::codegen::{Error, NodeRunner, ObservedSource, PeerInfo, ProducerRef, QoSProfile, Result, StandaloneConfig};
        pub type NodeBuilder<P = self::parameters::Parameters> = ::peppy::codegen::NodeBuilder<P>;
        pub use self::parameters::Parameters;
        pub mod parameters {
            #[derive(::peppy::codegen::serde::Deserialize)]
            #[serde(crate = "::peppy::codegen::serde")]
            pub struct Parameters {}
            impl ::peppy::codegen::NodeParameters for Parameters {
                fn descriptor() -> &'static ::peppy::codegen::NodeDescriptor {
                    ::core::unimplemented!()
                }
            }
        }
        #(#modules)*
    }
}

/// The entry categories, in the order they are generated, with their docs.
const CATEGORIES: &[(&str, &str)] = &[
    (
        "emitted_topics",
        "Topics this node emits, one module each with `Message` and `emit` (and `declare_publisher` with `build_message`).",
    ),
    (
        "consumed_topics",
        "Topics this node consumes, one module each with `Message`, `subscribe` and `on_next_message_received`: `<link_id>_<topic>` through a slot, `<topic>` for an external topic.",
    ),
    (
        "exposed_services",
        "Services this node exposes, one module each with `Request`, `Response` and `handle_next_request`.",
    ),
    (
        "consumed_services",
        "Services this node calls, one module `<link_id>_<service>` each with `Request`, `Response` and `poll`.",
    ),
    (
        "exposed_actions",
        "Actions this node exposes, one module each with `ActionHandle` (`expose`, `handle_goal_next_request`) and `GoalContext`.",
    ),
    (
        "consumed_actions",
        "Actions this node calls, one module `<link_id>_<action>` each with `GoalRequest` and `ActionHandle` (`fire_goal`, `on_next_feedback_message`, `get_result`, `cancel_goal`).",
    ),
];

/// The category docs of a `node/v1` node, where entries through a slot
/// nest under the slot's link_id (PeppyOS's module paths).
const LINK_CATEGORIES: &[&str] = &[
    "Topics this node emits, one module each with `Message`, `declare_publisher` and `build_message` (and `emit`): `<topic>` for its own, `<implements link_id>::<member>` for a contract's.",
    "Topics this node consumes: `<link_id>::<topic>` with `Message` and `subscribe`, and the slot's `bound_producer` / `bound_producers` next to its entries and in each of them.",
    "Services this node exposes, one module each with `Request`, `Response` and `handle_next_request`: `<service>` for its own, `<implements link_id>::<member>` for a contract's.",
    "Services this node calls: `<link_id>::<service>` with `Request`, `Response` and `poll`, and the slot's `bound_producer` / `bound_producers`.",
    "Actions this node exposes, one module each with `ActionHandle` (`expose`, `handle_goal_next_request`) and `GoalContext`: `<action>` for its own, `<implements link_id>::<member>` for a contract's.",
    "Actions this node calls: `<link_id>::<action>` with `GoalRequest` and `ActionHandle` (`fire_goal`, `on_next_feedback_message`, `get_result`, `cancel_goal`), and the slot's `bound_producer` / `bound_producers`.",
];

/// Names the runtime entry points use besides the fields.
pub(crate) const RESERVED_ARGS: &[&str] = &["node_runner", "message", "SPEC"];

pub(crate) struct Gen<'a> {
    pub(crate) node: &'a ResolvedNode,
    /// How the descriptor names the document (default: its path here).
    pub(crate) document_path: Option<String>,
    pub(crate) diags: Diagnostics,
    /// What compiles the test surfaces in.
    pub(crate) gate: TestGate,
}

/// One generated category module: its items and the paths (below the
/// category) of the `SPEC` statics the node descriptor lists.
#[derive(Default)]
pub(crate) struct Category {
    items: TokenStream,
    specs: Vec<Vec<Ident>>,
    /// Every entry module: the entry's index in the node's list of its
    /// category, and its path below the category (test surfaces name them).
    pub(crate) modules: Vec<(usize, Vec<Ident>)>,
    /// The conformed entries also re-exported under their own name: their
    /// full paths below the category.
    pub(crate) flat: Vec<Vec<Ident>>,
}

impl Gen<'_> {
    fn tree(&mut self) -> TokenStream {
        let layout = peppy_schema::layout::layout(self.node, &mut self.diags);
        let [
            emitted,
            consumed_topics,
            exposed,
            consumed_services,
            exposed_actions,
            consumed_actions,
        ] = std::array::from_fn(|i| self.category(&layout.categories[i], i));

        let spec_refs = |category: &str, c: &Category| -> Vec<TokenStream> {
            let cat = ident(category);
            c.specs
                .iter()
                .map(|path| quote!(&super::#cat::#(#path::)*SPEC))
                .collect()
        };
        let descriptor = params::Descriptor {
            document_path: self
                .document_path
                .clone()
                .unwrap_or_else(|| self.node.node.file.path().display().to_string()),
            model: peppy_schema::NodeModel::of(&self.node.node).to_json(),
            emitted_topics: spec_refs("emitted_topics", &emitted),
            consumed_topics: spec_refs("consumed_topics", &consumed_topics),
            exposed_services: spec_refs("exposed_services", &exposed),
            exposed_actions: spec_refs("exposed_actions", &exposed_actions),
        };
        let parameters = params::parameters(self.node, &descriptor, &mut self.diags);

        let layout = Layout {
            emitted_topics: emitted.modules.clone(),
            consumed_topics: consumed_topics.modules.clone(),
            exposed_services: exposed.modules.clone(),
            consumed_services: consumed_services.modules.clone(),
            exposed_actions: exposed_actions.modules.clone(),
            consumed_actions: consumed_actions.modules.clone(),
            emitted_taps: layout.categories[0].tap_names(),
            exposed_services_flat: exposed.flat.clone(),
            exposed_actions_flat: exposed_actions.flat.clone(),
        };
        let test_surfaces = self.test_surfaces(&layout, self.gate);
        let paired_topics = self.paired_topics();

        let source = short_location(&self.node.node.name_loc);
        let identity = self.node.node.identity();
        let categories = [
            emitted,
            consumed_topics,
            exposed,
            consumed_services,
            exposed_actions,
            consumed_actions,
        ];
        let peppylib = self.peppylib();
        let modules = CATEGORIES
            .iter()
            .zip(categories)
            .enumerate()
            .map(|(i, ((name, doc), c))| {
                let doc = if peppylib { LINK_CATEGORIES[i] } else { doc };
                let id = ident(name);
                let items = c.items;
                let doc = crate::docs::Doc::new(format!(
                    "{doc}\n\nGenerated from node `{identity}` (`{source}`)."
                ));
                quote! {
                    #doc
                    #[allow(dead_code)]
                    pub mod #id {
                        #items
                    }
                }
            });
        let params_doc = crate::docs::Doc::new(format!(
            "The parameters of node `{identity}` (`execution.parameters`), and the node's descriptor."
        ));
        quote! {
            #[doc = " Re-exported from peppy, so node code needs only `peppygen`."]
            pub use ::peppy::codegen::{Error, NodeRunner, ObservedSource, PeerInfo, ProducerRef, QoSProfile, Result, StandaloneConfig};
            #[doc = " Builds and runs this node: `NodeBuilder::new().run(|params: Parameters, runner| async move { Ok(()) })`."]
            #[allow(dead_code)]
            pub type NodeBuilder<P = self::parameters::Parameters> = ::peppy::codegen::NodeBuilder<P>;
            #[doc = " This node's parameters."]
            pub use self::parameters::Parameters;
            #params_doc
            #[allow(dead_code)]
            pub mod parameters {
                #parameters
            }
            #(#modules)*
            #paired_topics
            #test_surfaces
        }
    }

    /// One category's module, walking the layout peppy-schema decided:
    /// each entry's module, the modules that group them, and the aliases.
    fn category(&mut self, layout: &CategoryLayout, category_index: usize) -> Category {
        let mut category = Category::default();
        let kind = layout.kind;
        category.items = self.modules(
            &layout.modules,
            kind,
            category_index,
            &mut Vec::new(),
            None,
            &mut category,
        );
        for alias in &layout.aliases {
            let path: Vec<Ident> = alias.path.iter().map(|m| ident(m)).collect();
            let doc = crate::docs::Doc::new(format!(
                "The {kind} `{}` of interface `{}` under its own name (no other {kind} of this node generates module `{}`).",
                alias.name, alias.interface, alias.module
            ));
            category.items.extend(quote! {
                #doc
                pub use self::#(#path)::*;
            });
            category.flat.push(path);
        }
        category
    }

    /// The modules `nodes` (below `path`); `slot` is the cardinality of the
    /// slot they are consumed through, when there is one.
    fn modules(
        &mut self,
        nodes: &[ModuleNode],
        kind: EntryKind,
        category_index: usize,
        path: &mut Vec<Ident>,
        slot: Option<Option<Cardinality>>,
        category: &mut Category,
    ) -> TokenStream {
        let mut out = TokenStream::new();
        for n in nodes {
            let id = ident(&n.name);
            path.push(id.clone());
            let (doc, items) = match &n.role {
                ModuleRole::Entry(index) => {
                    let (doc, body, listed) = self.entry(category_index, *index);
                    category.modules.push((*index, path.clone()));
                    if listed {
                        category.specs.push(path.clone());
                    }
                    let accessor = slot.map(entry_accessor).unwrap_or_default();
                    (doc, quote!(#accessor #body))
                }
                ModuleRole::Interface(name) => (
                    format!("The {kind}s of interface `{name}`, by tag."),
                    self.modules(&n.children, kind, category_index, path, slot, category),
                ),
                ModuleRole::InterfaceTag(interface) => (
                    format!("The {kind}s of interface `{interface}`, which this node conforms to."),
                    self.modules(&n.children, kind, category_index, path, slot, category),
                ),
                ModuleRole::Implements {
                    link_id,
                    contract,
                    loc,
                } => (
                    format!(
                        "The {kind}s of contract `{contract}`, which this node implements as slot `{link_id}` (`{}`).",
                        short_location(loc)
                    ),
                    self.modules(&n.children, kind, category_index, path, slot, category),
                ),
                ModuleRole::Slot {
                    link_id,
                    cardinality,
                    loc,
                } => {
                    let mut items = slot_accessor(link_id, *cardinality);
                    items.extend(self.modules(
                        &n.children,
                        kind,
                        category_index,
                        path,
                        Some(*cardinality),
                        category,
                    ));
                    let shown = cardinality
                        .map(|c| format!(", cardinality `{c}`"))
                        .unwrap_or_default();
                    (
                        format!(
                            "The {kind}s this node consumes through slot `{link_id}` (`{}`{shown}).",
                            short_location(loc)
                        ),
                        items,
                    )
                }
            };
            path.pop();
            let doc = crate::docs::Doc::new(doc);
            out.extend(quote! {
                #doc
                pub mod #id {
                    #items
                }
            });
        }
        out
    }

    /// Entry `index` of category `category_index`: its doc, its body, and
    /// whether the node descriptor lists its `SPEC`.
    fn entry(&mut self, category_index: usize, index: usize) -> (String, TokenStream, bool) {
        let node = self.node;
        match category_index {
            0 => {
                let p = &node.emitted_topics[index];
                let doc = entry_doc(EntryKind::Topic, &p.decl.name, &p.origin, &p.decl.loc);
                (doc, self.emitted_topic(p), true)
            }
            1 => {
                let t = &node.consumed_topics[index];
                (consumed_topic_doc(t), self.consumed_topic(t), true)
            }
            2 => {
                let p = &node.exposed_services[index];
                let doc = entry_doc(EntryKind::Service, &p.decl.name, &p.origin, &p.decl.loc);
                (doc, self.exposed_service(p), true)
            }
            3 => {
                let c = &node.consumed_services[index];
                (
                    call_doc(EntryKind::Service, c),
                    self.consumed_service(c),
                    false,
                )
            }
            4 => {
                let p = &node.exposed_actions[index];
                let doc = entry_doc(EntryKind::Action, &p.decl.name, &p.origin, &p.decl.loc);
                (doc, self.exposed_action(p), true)
            }
            _ => {
                let c = &node.consumed_actions[index];
                (
                    call_doc(EntryKind::Action, c),
                    self.consumed_action(c),
                    false,
                )
            }
        }
    }

    /// Whether the node's code is on PeppyOS's `peppylib` API, whose
    /// entries through a slot nest under the slot's link_id.
    pub(crate) fn peppylib(&self) -> bool {
        self.node.node.api == NodeApi::Peppylib
    }

    /// `emitted_topics::<topic>`: `Message`, `SPEC`, `emit`, `set_shm_threshold`.
    fn emitted_topic(&mut self, p: &Provided<TopicDecl>) -> TokenStream {
        let decl = &p.decl;
        let mut names = Names::with_fixed(&["Message"]);
        let mut structs = Structs {
            names: &mut names,
            diags: &mut self.diags,
            out: TokenStream::new(),
        };
        let doc = format!("A message of topic `{}`.", decl.name);
        structs.message("Message", "Message", decl.format.as_ref(), &doc);
        let types = structs.out;
        let fields = fields_of(decl.format.as_ref());
        let a = args("Message", fields, RESERVED_ARGS);
        let params = &a.params;
        let inits = &a.inits;
        let allow_snake = snake_allow(fields);
        let allow_many = many_args_allow(fields.len() + 1);
        let name = &decl.name;
        let owner = owner(&p.origin, true);
        let qos = qos(decl.qos);
        let format = format_spec(decl.format.as_ref());
        let emit_doc = crate::docs::Doc::new(format!(
            "Publishes one message on `{name}`, the fields in declaration order. The message is encoded by this call and sent when the returned future is first polled."
        ));
        quote! {
            #types

            #[doc = " What the runtime knows about this topic."]
            pub(crate) static SPEC: ::peppy::codegen::TopicSpec = ::peppy::codegen::TopicSpec {
                owner: #owner,
                name: #name,
                qos: #qos,
                format: #format,
            };

            #emit_doc
            #allow_snake
            #allow_many
            pub fn emit(
                node_runner: &::peppy::codegen::NodeRunner,
                #(#params),*
            ) -> impl ::core::future::Future<Output = ::peppy::codegen::Result<()>> + ::core::marker::Send + '_ {
                ::peppy::codegen::emit(node_runner, &SPEC, &Message { #(#inits),* })
            }

            #[doc = " Builds one message of this topic from its fields, in declaration order, for a publisher of `declare_publisher` to send. It is encoded when published."]
            #allow_snake
            #allow_many
            pub fn build_message(#(#params),*) -> ::peppy::codegen::Result<::peppy::codegen::OutgoingMessage> {
                ::core::result::Result::Ok(::peppy::codegen::OutgoingMessage::new(&SPEC, Message { #(#inits),* }))
            }

            #[doc = " Declares a publisher of this topic: declare it once, then `publisher.publish(build_message(..)?)` per message. It holds the node, so it can move into a spawned task."]
            pub async fn declare_publisher(
                node_runner: &::peppy::codegen::NodeRunner,
            ) -> ::peppy::codegen::Result<::peppy::codegen::TopicPublisher> {
                ::peppy::codegen::declare_publisher(node_runner, &SPEC).await
            }

            #[doc = " Sends messages of this topic of at least `threshold` bytes through shared memory to readers on this host (`None`: never), overriding the node's threshold (default 4 KiB; `PEPPY_SHM` or `NodeBuilder::shared_memory`)."]
            pub fn set_shm_threshold(
                node_runner: &::peppy::codegen::NodeRunner,
                threshold: ::core::option::Option<usize>,
            ) {
                node_runner.set_shm_threshold(&SPEC, threshold);
            }
        }
    }

    /// `consumed_topics::<module>`: `Message`, `SPEC`, `on_next_message_received`,
    /// `on_next_payload_received`.
    fn consumed_topic(&mut self, t: &ResolvedTopic) -> TokenStream {
        let mut names = Names::with_fixed(&["Message"]);
        let mut structs = Structs {
            names: &mut names,
            diags: &mut self.diags,
            out: TokenStream::new(),
        };
        let doc = format!("A message of topic `{}`.", t.name);
        structs.message("Message", "Message", t.format.as_ref(), &doc);
        let types = structs.out;
        let link_id = match &t.slot {
            Some(s) => {
                let l = &s.link_id;
                quote!(::core::option::Option::Some(#l))
            }
            None => quote!(::core::option::Option::None),
        };
        let owner = match &t.origin {
            Some(o) => owner(o, false),
            None => quote!(::peppy::codegen::OwnerSpec::Any),
        };
        let name = &t.name;
        let qos = qos(t.qos);
        let format = format_spec(t.format.as_ref());
        let reads = self.topic_readers(t);
        quote! {
            #types

            #[doc = " What the runtime knows about this topic."]
            pub(crate) static SPEC: ::peppy::codegen::ConsumedTopicSpec = ::peppy::codegen::ConsumedTopicSpec {
                link_id: #link_id,
                owner: #owner,
                name: #name,
                qos: #qos,
                format: #format,
            };

            #[doc = " A held subscription to this topic: `next()` yields `(producer, message)`, `None` once the node stops."]
            pub type Subscription = ::peppy::codegen::Subscription<Message>;

            #[doc = " Subscribes to this topic: call it once, then loop on `Subscription::next`. Messages are queued from node start-up, so none is lost before the first call or between two."]
            pub async fn subscribe(
                node_runner: &::peppy::codegen::NodeRunner,
            ) -> ::peppy::codegen::Result<Subscription> {
                ::peppy::codegen::subscribe(node_runner, &SPEC).await
            }

            #reads
        }
    }

    /// The readers of a consumed topic. External topics take the
    /// original's third argument, `from_instance_id` (no binding names
    /// their producers), and so does every consumed topic of a legacy
    /// `schema_version: 1` node, whose published code passes it; linked
    /// topics of a `node_v1` node take two, as the current docs show.
    fn topic_readers(&self, t: &ResolvedTopic) -> TokenStream {
        let by_instance = t.slot.is_none() || self.node.node.legacy;
        let message_doc = " Waits for the next message: `(producer instance id, message)`. Messages are queued from node start-up, so none is lost between calls. `from_core_node: Some(id)` keeps only messages from instances started by that launch. `Error::ShuttingDown` once the node stops, after a short pause when called on a stopped node, so a loop ignoring it does not spin.";
        let payload_doc = " Like `on_next_message_received`, without decoding: the message's bytes where they arrived. A large message from this host is read in place from the producer's shared memory; `Payload::decode::<Message>()` decodes it, and a `Decoder` walking `Payload::bytes()` borrows byte fields without copying them.";
        if !by_instance {
            return quote! {
                #[doc = #message_doc]
                pub async fn on_next_message_received(
                    node_runner: &::peppy::codegen::NodeRunner,
                    from_core_node: ::core::option::Option<&str>,
                ) -> ::peppy::codegen::Result<(::std::string::String, Message)> {
                    ::peppy::codegen::next_message(node_runner, &SPEC, from_core_node).await
                }

                #[doc = #payload_doc]
                pub async fn on_next_payload_received(
                    node_runner: &::peppy::codegen::NodeRunner,
                    from_core_node: ::core::option::Option<&str>,
                ) -> ::peppy::codegen::Result<(::std::string::String, ::peppy::codegen::Payload)> {
                    ::peppy::codegen::next_payload(node_runner, &SPEC, from_core_node).await
                }
            };
        }
        let instance_doc =
            " `from_instance_id: Some(id)` keeps only messages from that producer instance.";
        quote! {
            #[doc = #message_doc]
            #[doc = ""]
            #[doc = #instance_doc]
            pub async fn on_next_message_received(
                node_runner: &::peppy::codegen::NodeRunner,
                from_core_node: ::core::option::Option<&str>,
                from_instance_id: ::core::option::Option<&str>,
            ) -> ::peppy::codegen::Result<(::std::string::String, Message)> {
                let senders = ::peppy::codegen::Senders {
                    core_node: from_core_node,
                    instance_id: from_instance_id,
                };
                ::peppy::codegen::next_message_from(node_runner, &SPEC, senders).await
            }

            #[doc = #payload_doc]
            #[doc = ""]
            #[doc = #instance_doc]
            pub async fn on_next_payload_received(
                node_runner: &::peppy::codegen::NodeRunner,
                from_core_node: ::core::option::Option<&str>,
                from_instance_id: ::core::option::Option<&str>,
            ) -> ::peppy::codegen::Result<(::std::string::String, ::peppy::codegen::Payload)> {
                let senders = ::peppy::codegen::Senders {
                    core_node: from_core_node,
                    instance_id: from_instance_id,
                };
                ::peppy::codegen::next_payload_from(node_runner, &SPEC, senders).await
            }
        }
    }

    /// `exposed_services::<service>`: `Request`, `Response`, `SPEC`,
    /// `handle_next_request`.
    ///
    /// Long on purpose: most of it is one `quote!` template, kept whole so
    /// the generated module reads top to bottom as users see it.
    fn exposed_service(&mut self, p: &Provided<ServiceDecl>) -> TokenStream {
        let decl = &p.decl;
        let prefix = type_prefix(&decl.name);
        let mut fixed = vec!["Request"];
        if decl.request.is_some() {
            fixed.push("RequestData");
        }
        if decl.response.is_some() {
            fixed.push("Response");
        }
        let mut names = Names::with_fixed(&fixed);
        let mut structs = Structs {
            names: &mut names,
            diags: &mut self.diags,
            out: TokenStream::new(),
        };
        let name = &decl.name;
        if let Some(req) = &decl.request {
            let doc = format!("The request data of service `{name}`.");
            structs.message("RequestData", &prefix, Some(req), &doc);
        }
        if let Some(resp) = &decl.response {
            let doc = format!("The response of service `{name}`; build it with `Response::new`.");
            structs.message("Response", "Response", Some(resp), &doc);
        }
        let types = structs.out;

        let (data_field, data_type, data_init) = match &decl.request {
            Some(_) => (
                quote! {
                    #[doc = " The request."]
                    pub data: RequestData,
                },
                quote!(RequestData),
                quote!(data,),
            ),
            None => (quote!(), quote!(()), quote!()),
        };
        let data_pat = if decl.request.is_some() {
            quote!(data)
        } else {
            quote!(())
        };
        let (response_type, constructor) = match &decl.response {
            Some(resp) => {
                let a = args("Response", &resp.fields, &[]);
                let params = &a.params;
                let inits = &a.inits;
                let allow_snake = snake_allow(&resp.fields);
                let allow_many = many_args_allow(resp.fields.len());
                (
                    quote!(Response),
                    quote! {
                        impl Response {
                            #[doc = " A response from its fields, in declaration order."]
                            #allow_snake
                            #allow_many
                            pub fn new(#(#params),*) -> Self {
                                Self { #(#inits),* }
                            }
                        }
                    },
                )
            }
            None => (quote!(()), quote!()),
        };
        let owner = owner(&p.origin, true);
        let request_format = format_spec(decl.request.as_ref());
        let response_format = format_spec(decl.response.as_ref());
        let request_doc = crate::docs::Doc::new(format!(
            "A request to service `{name}`, with the caller's identity{}.",
            if decl.request.is_some() {
                " and its data"
            } else {
                " (the service takes no request data)"
            }
        ));
        let handle_doc = crate::docs::Doc::new(format!(
            "Serves the next request of `{name}` with `handler`; call it in a loop. Requests are queued from node start-up, so concurrent callers are all served. A handler error is returned to the caller as its reason{}. `Error::ShuttingDown` once the node stops, after a short pause when called on a stopped node, so a loop ignoring it does not spin.",
            if decl.response.is_some() {
                ""
            } else {
                " (the service has no response data: the handler returns `Ok(())`)"
            }
        ));
        quote! {
            #types

            #constructor

            #request_doc
            #[derive(::core::fmt::Debug, ::core::clone::Clone, ::core::cmp::PartialEq)]
            pub struct Request {
                #[doc = " The caller's instance id."]
                pub instance_id: ::std::string::String,
                #[doc = " The launch (core node) that started the caller."]
                pub core_node: ::std::string::String,
                #data_field
            }

            #[doc = " What the runtime knows about this service."]
            pub(crate) static SPEC: ::peppy::codegen::ServiceSpec = ::peppy::codegen::ServiceSpec {
                owner: #owner,
                name: #name,
                request: #request_format,
                response: #response_format,
            };

            #handle_doc
            pub async fn handle_next_request<F>(
                node_runner: &::peppy::codegen::NodeRunner,
                handler: F,
            ) -> ::peppy::codegen::Result<()>
            where
                F: ::core::ops::FnOnce(Request) -> ::peppy::codegen::Result<#response_type>,
            {
                ::peppy::codegen::handle_next(
                    node_runner,
                    &SPEC,
                    |caller: ::peppy::codegen::Caller, #data_pat: #data_type| {
                        handler(Request {
                            instance_id: caller.instance_id,
                            core_node: caller.core_node,
                            #data_init
                        })
                    },
                )
                .await
            }
        }
    }

    /// `consumed_services::<link_id>_<service>`: `Request`, `Response`,
    /// `SPEC`, `poll`.
    fn consumed_service(&mut self, s: &ResolvedCall<ServiceDecl>) -> TokenStream {
        let decl = &s.decl;
        let prefix = type_prefix(&decl.name);
        let mut fixed = vec!["Response"];
        if decl.request.is_some() {
            fixed.push("Request");
        }
        if decl.response.is_some() {
            fixed.push("ResponseData");
        }
        let mut names = Names::with_fixed(&fixed);
        let mut structs = Structs {
            names: &mut names,
            diags: &mut self.diags,
            out: TokenStream::new(),
        };
        let name = &decl.name;
        if let Some(req) = &decl.request {
            let doc = format!("A request to service `{name}`; build it with `Request::new`.");
            structs.message("Request", &prefix, Some(req), &doc);
        }
        if let Some(resp) = &decl.response {
            let doc = format!("The response data of service `{name}`.");
            structs.message("ResponseData", "ResponseData", Some(resp), &doc);
        }
        let types = structs.out;
        let constructor = match &decl.request {
            Some(req) => {
                let a = args(&prefix, &req.fields, &[]);
                let params = &a.params;
                let inits = &a.inits;
                let allow_snake = snake_allow(&req.fields);
                let allow_many = many_args_allow(req.fields.len());
                quote! {
                    impl Request {
                        #[doc = " A request from its fields, in declaration order."]
                        #allow_snake
                        #allow_many
                        pub fn new(#(#params),*) -> Self {
                            Self { #(#inits),* }
                        }
                    }
                }
            }
            None => quote!(),
        };
        let (request_param, request_ref) = match &decl.request {
            Some(_) => (quote!(request: Request,), quote!(&request)),
            None => (quote!(), quote!(&())),
        };
        let (data_field, data_type, data_init) = match &decl.response {
            Some(_) => (
                quote! {
                    #[doc = " The response."]
                    pub data: ResponseData,
                },
                quote!(ResponseData),
                quote!(data: reply.data,),
            ),
            None => (quote!(), quote!(()), quote!()),
        };
        let link_id = &s.slot.link_id;
        let owner = owner(&s.origin, false);
        let request_format = format_spec(decl.request.as_ref());
        let response_format = format_spec(decl.response.as_ref());
        let errors = "Fails with `ServiceUnreachable` (nobody answered), `ServiceTimeout` (accepted, no reply in time) or `ServiceError` (the handler failed).";
        let (poll_doc, target_param, call) = if self.peppylib() {
            (
                format!(
                    "Calls `{name}` on `target`, one of the producers bound to slot `{link_id}` (`bound_producer` / `bound_producers`), and waits at most `timeout` for the response. `TargetNotBound` for any other target, before anything is sent. {errors}"
                ),
                quote!(target: &::peppy::codegen::ProducerRef,),
                quote!(::peppy::codegen::call_to(node_runner, &SPEC, target, timeout, #request_ref)),
            )
        } else {
            (
                format!(
                    "Calls `{name}` through slot `{link_id}` and waits at most `timeout` for the response: straight to the bound producer when the slot is pinned, else to the first producer the slot accepts. {errors}"
                ),
                quote!(),
                quote!(::peppy::codegen::call(node_runner, &SPEC, timeout, #request_ref)),
            )
        };
        let poll_doc = crate::docs::Doc::new(poll_doc);
        let response_constructor = crate::actions::data_constructor(
            "ResponseData",
            "ResponseData",
            decl.response.as_ref(),
        );
        // PeppyOS's current API answers a call without response data with
        // `()`; the emit API with the server's identity.
        let (poll_type, poll_answer) = if self.peppylib() && decl.response.is_none() {
            (quote!(()), quote!(::core::result::Result::Ok(())))
        } else {
            (
                quote!(Response),
                quote! {
                    ::core::result::Result::Ok(Response {
                        instance_id: reply.instance_id,
                        core_node: reply.core_node,
                        #data_init
                    })
                },
            )
        };
        quote! {
            #types

            #constructor

            #response_constructor

            #[doc = " A response with the server's identity."]
            #[derive(::core::fmt::Debug, ::core::clone::Clone, ::core::cmp::PartialEq)]
            pub struct Response {
                #[doc = " The server's instance id."]
                pub instance_id: ::std::string::String,
                #[doc = " The launch (core node) that started the server."]
                pub core_node: ::std::string::String,
                #data_field
            }

            #[doc = " What the runtime knows about this service."]
            pub(crate) static SPEC: ::peppy::codegen::ConsumedServiceSpec = ::peppy::codegen::ConsumedServiceSpec {
                link_id: #link_id,
                owner: #owner,
                name: #name,
                request: #request_format,
                response: #response_format,
            };

            #poll_doc
            pub async fn poll(
                node_runner: &::peppy::codegen::NodeRunner,
                #target_param
                timeout: ::core::time::Duration,
                #request_param
            ) -> ::peppy::codegen::Result<#poll_type> {
                #[allow(unused_variables)]
                let reply: ::peppy::codegen::Reply<#data_type> = #call.await?;
                #poll_answer
            }
        }
    }
}

pub(crate) fn fields_of(format: Option<&MessageFormat>) -> &[peppy_schema::Field] {
    format.map(|f| f.fields.as_slice()).unwrap_or(&[])
}

fn capitalised(kind: EntryKind) -> String {
    let s = kind.to_string();
    let mut c = s.chars();
    match c.next() {
        Some(f) => f.to_uppercase().chain(c).collect(),
        None => s,
    }
}

fn origin_text(origin: &Origin) -> String {
    match origin {
        Origin::Node(id) => format!("node `{id}`"),
        Origin::Interface(id) => format!("interface `{id}`"),
    }
}

fn entry_doc(kind: EntryKind, name: &str, origin: &Origin, loc: &Loc) -> String {
    let from = match origin {
        Origin::Node(_) => "declared by this node".to_string(),
        Origin::Interface(id) => format!("inherited from interface `{id}`"),
    };
    format!(
        "{} `{name}`, {from} (`{}`).",
        capitalised(kind),
        short_location(loc)
    )
}

/// The doc of a consumed service or action module.
fn call_doc<T: Declared>(kind: EntryKind, c: &ResolvedCall<T>) -> String {
    format!(
        "Calls {kind} `{}` of {}, through slot `{}` (declared at `{}`; the {kind} is declared at `{}`).",
        c.decl.name(),
        origin_text(&c.origin),
        c.slot.link_id,
        short_location(&c.loc),
        short_location(c.decl.decl_loc())
    )
}

/// The bound-producer accessor of a `node/v1` slot, by cardinality:
/// `bound_producer` for `one` (`&ProducerRef`) and `zero_or_one` (an
/// `Option`), `bound_producers` for the others (`NonEmptyProducers` for
/// `one_or_more`, a slice for `zero_or_more`, in link order).
fn slot_accessor(link_id: &str, cardinality: Option<Cardinality>) -> TokenStream {
    let Some(cardinality) = cardinality else {
        return TokenStream::new();
    };
    match cardinality {
        Cardinality::One => {
            let doc = crate::docs::Doc::new(format!(
                "The producer instance bound to slot `{link_id}` (cardinality `one`). The node does not start unless the slot is bound to exactly one producer."
            ));
            quote! {
                #doc
                pub fn bound_producer(node_runner: &::peppy::codegen::NodeRunner) -> &::peppy::codegen::ProducerRef {
                    ::peppy::codegen::sole_bound_producer(node_runner, #link_id)
                }
            }
        }
        Cardinality::ZeroOrOne => {
            let doc = crate::docs::Doc::new(format!(
                "The producer instance bound to slot `{link_id}` (cardinality `zero_or_one`), `None` when the slot is vacant."
            ));
            quote! {
                #doc
                pub fn bound_producer(
                    node_runner: &::peppy::codegen::NodeRunner,
                ) -> ::core::option::Option<&::peppy::codegen::ProducerRef> {
                    ::peppy::codegen::optional_bound_producer(node_runner, #link_id)
                }
            }
        }
        Cardinality::OneOrMore => {
            let doc = crate::docs::Doc::new(format!(
                "The producer instances bound to slot `{link_id}` (cardinality `one_or_more`), in link order, fixed for the instance's life; never empty, so `first()` needs no `Option`."
            ));
            quote! {
                #doc
                pub fn bound_producers(
                    node_runner: &::peppy::codegen::NodeRunner,
                ) -> ::peppy::codegen::NonEmptyProducers<'_> {
                    ::peppy::codegen::non_empty_bound_producers(node_runner, #link_id)
                }
            }
        }
        Cardinality::ZeroOrMore => {
            let doc = crate::docs::Doc::new(format!(
                "The producer instances bound to slot `{link_id}` (cardinality `zero_or_more`), in link order, fixed for the instance's life; possibly empty."
            ));
            quote! {
                #doc
                pub fn bound_producers(
                    node_runner: &::peppy::codegen::NodeRunner,
                ) -> &[::peppy::codegen::ProducerRef] {
                    ::peppy::codegen::bound_producers(node_runner, #link_id)
                }
            }
        }
    }
}

/// The slot's accessor, repeated in each entry module of the slot
/// (`consumed_actions::<slot>::<action>::bound_producer`), where
/// peppylib-API code reaches for it.
fn entry_accessor(cardinality: Option<Cardinality>) -> TokenStream {
    match cardinality {
        None => TokenStream::new(),
        Some(Cardinality::One | Cardinality::ZeroOrOne) => quote! {
            #[doc = " The slot's bound producer (see the slot's module)."]
            pub use super::bound_producer;
        },
        Some(Cardinality::OneOrMore | Cardinality::ZeroOrMore) => quote! {
            #[doc = " The slot's bound producers (see the slot's module)."]
            pub use super::bound_producers;
        },
    }
}

fn consumed_topic_doc(t: &ResolvedTopic) -> String {
    match (&t.slot, &t.origin) {
        (Some(slot), Some(origin)) => format!(
            "Receives topic `{}` of {} through slot `{}` (declared at `{}`).",
            t.name,
            origin_text(origin),
            slot.link_id,
            short_location(&t.loc)
        ),
        _ => format!(
            "Receives topic `{}` from any node that emits it in this format (external, declared at `{}`).",
            t.name,
            short_location(&t.loc)
        ),
    }
}

/// The `OwnerSpec` of an entry; `own` entries of this node are `Own`.
pub(crate) fn owner(origin: &Origin, own: bool) -> TokenStream {
    match origin {
        Origin::Node(_) if own => quote!(::peppy::codegen::OwnerSpec::Own),
        Origin::Node(id) => {
            let (name, tag) = (&id.name, &id.tag);
            quote!(::peppy::codegen::OwnerSpec::Node { name: #name, tag: #tag })
        }
        Origin::Interface(id) => {
            let (name, tag) = (&id.name, &id.tag);
            quote!(::peppy::codegen::OwnerSpec::Interface { name: #name, tag: #tag })
        }
    }
}

pub(crate) fn qos(q: QosProfile) -> TokenStream {
    match q {
        QosProfile::SensorData => quote!(::peppy::codegen::QosProfile::SensorData),
        QosProfile::Standard => quote!(::peppy::codegen::QosProfile::Standard),
        QosProfile::Reliable => quote!(::peppy::codegen::QosProfile::Reliable),
        QosProfile::Critical => quote!(::peppy::codegen::QosProfile::Critical),
    }
}
