//! `paired_topics`: one module per pairing slot, one per topic of it
//! (docs/PAIRINGS.md §4). A participant's module offers `paired`,
//! `wait_paired`, and per topic `build_message`/`declare_publisher` for what
//! its role emits or `subscribe` for the counterpart's topics it consumes;
//! an observer's offers `source`/`sources` and a fanned-in `subscribe`.

use peppy_schema::{Cardinality, PairingTopicUse, ResolvedPairing};
use proc_macro2::TokenStream;
use quote::quote;

use crate::generate::{Gen, RESERVED_ARGS, fields_of, qos};
use crate::naming::{NameKind, Names, ident, short_location};
use crate::types::{Structs, args, format_spec, many_args_allow, snake_allow};

impl Gen<'_> {
    /// The `paired_topics` module, or nothing for a node without pairing
    /// slots.
    pub(crate) fn paired_topics(&mut self) -> TokenStream {
        let node = self.node;
        if node.pairings.is_empty() {
            return TokenStream::new();
        }
        let mut slots = TokenStream::new();
        for p in &node.pairings {
            slots.extend(self.pairing_slot(p));
        }
        let identity = node.node.identity();
        let doc = crate::docs::Doc::new(format!(
            "Pairing topics, `<link_id>::<topic>`: a participant's `paired`, `wait_paired`, `build_message` / `declare_publisher` for what its role emits and `subscribe` for the counterpart's topics; an observer's `source` / `sources` and `subscribe`.\n\nGenerated from node `{identity}` (`{}`).",
            short_location(&node.node.name_loc)
        ));
        quote! {
            #doc
            #[allow(dead_code)]
            pub mod paired_topics {
                #slots
            }
        }
    }

    fn pairing_slot(&mut self, p: &ResolvedPairing) -> TokenStream {
        let slot = &p.slot;
        let link = &slot.link_id;
        let mut names = Names::default();
        let mut topics = TokenStream::new();
        let what = |t: &PairingTopicUse| {
            format!(
                "pairing topic `{}` of slot `{}`",
                t.topic.decl.name, slot.link_id
            )
        };
        for t in &p.emitted {
            if names.claim(
                NameKind::module_of(self.node.node.spelling),
                &t.topic.decl.name,
                &what(t),
                &t.loc,
                &mut self.diags,
            ) {
                topics.extend(self.paired_topic(p, t, true));
            }
        }
        for t in &p.consumed {
            if names.claim(
                NameKind::module_of(self.node.node.spelling),
                &t.topic.decl.name,
                &what(t),
                &t.loc,
                &mut self.diags,
            ) {
                topics.extend(self.paired_topic(p, t, false));
            }
        }
        let id = ident(link);
        let role = if slot.observer {
            format!("observes role `{}`", slot.role)
        } else {
            format!("plays role `{}`", slot.role)
        };
        let doc = crate::docs::Doc::new(format!(
            "Pairing slot `{link}`: {role} of pairing `{}:{}`.",
            slot.pairing.name, slot.pairing.tag
        ));
        let accessors = slot_accessors(p);
        quote! {
            #doc
            pub mod #id {
                #accessors
                #topics
            }
        }
    }

    /// `paired_topics::<link_id>::<topic>`.
    fn paired_topic(
        &mut self,
        p: &ResolvedPairing,
        t: &PairingTopicUse,
        emitted: bool,
    ) -> TokenStream {
        let slot = &p.slot;
        let decl = &t.topic.decl;
        let mut names = Names::with_fixed(&["Message"]);
        let mut structs = Structs {
            names: &mut names,
            diags: &mut self.diags,
            out: TokenStream::new(),
        };
        let doc = format!(
            "A message of pairing topic `{}` (emitted by role `{}`).",
            decl.name, t.topic.emitted_by
        );
        structs.message("Message", "Message", decl.format.as_ref(), &doc);
        let types = structs.out;
        let name = &decl.name;
        let link = &slot.link_id;
        let pairing = &slot.pairing.name;
        let tag = &slot.pairing.tag;
        let qos = qos(decl.qos);
        let format = format_spec(decl.format.as_ref());
        let accessors = slot_accessors(p);
        let body = if emitted {
            let fields = fields_of(decl.format.as_ref());
            let a = args("Message", fields, RESERVED_ARGS);
            let params = &a.params;
            let inits = &a.inits;
            let allow_snake = snake_allow(fields);
            let allow_many = many_args_allow(fields.len());
            quote! {
                #[doc = " What the runtime knows about this topic."]
                pub(crate) static SPEC: ::peppy::codegen::PairedTopicSpec = ::peppy::codegen::PairedTopicSpec {
                    link_id: LINK_ID,
                    topic: ::peppy::codegen::TopicSpec {
                        owner: ::peppy::codegen::OwnerSpec::Any,
                        name: TOPIC_NAME,
                        qos: #qos,
                        format: #format,
                    },
                };

                #[doc = " Builds one message of this topic from its fields, in declaration order, for a publisher of `declare_publisher` to send."]
                #allow_snake
                #allow_many
                pub fn build_message(#(#params),*) -> ::peppy::codegen::Result<::peppy::codegen::OutgoingMessage> {
                    ::core::result::Result::Ok(::peppy::codegen::OutgoingMessage::new(&SPEC.topic, Message { #(#inits),* }))
                }

                #[doc = " Declares a publisher of this topic: it sends to the current peer, and sends nothing (successfully) while the slot is unpaired."]
                pub async fn declare_publisher(
                    node_runner: &::peppy::codegen::NodeRunner,
                ) -> ::peppy::codegen::Result<::peppy::codegen::PairedPublisher> {
                    ::peppy::codegen::declare_paired_publisher(node_runner, &SPEC).await
                }
            }
        } else {
            let (sub_type, subscribe_fn, sub_doc) = if slot.observer {
                (
                    quote!(::peppy::codegen::ObservedSubscription<Message>),
                    quote!(::peppy::codegen::subscribe_observed),
                    " A held subscription over every source of the slot: `next()` yields `(ObservedSource, message)`, `None` once the node stops.",
                )
            } else {
                (
                    quote!(::peppy::codegen::PairedSubscription<Message>),
                    quote!(::peppy::codegen::subscribe_paired),
                    " A held subscription to the peer's topic: `next()` yields `(PeerInfo, message)` from the current peer only, waits while unpaired, and yields `None` once the node stops.",
                )
            };
            quote! {
                #[doc = " What the runtime knows about this topic."]
                pub(crate) static SPEC: ::peppy::codegen::ConsumedPairedTopicSpec = ::peppy::codegen::ConsumedPairedTopicSpec {
                    link_id: LINK_ID,
                    topic: ::peppy::codegen::ConsumedTopicSpec {
                        link_id: ::core::option::Option::Some(LINK_ID),
                        owner: ::peppy::codegen::OwnerSpec::Any,
                        name: TOPIC_NAME,
                        qos: #qos,
                        format: #format,
                    },
                };

                #[doc = #sub_doc]
                pub type Subscription = #sub_type;

                #[doc = " Subscribes to this topic: call it once, then loop on `Subscription::next`."]
                pub async fn subscribe(
                    node_runner: &::peppy::codegen::NodeRunner,
                ) -> ::peppy::codegen::Result<Subscription> {
                    #subscribe_fn(node_runner, &SPEC).await
                }
            }
        };
        let id = ident(name);
        let doc = crate::docs::Doc::new(format!(
            "Pairing topic `{name}` through slot `{link}` (listed at `{}`).",
            short_location(&t.loc)
        ));
        quote! {
            #doc
            pub mod #id {
                #types

                #[doc = " The topic's name."]
                pub const TOPIC_NAME: &str = #name;
                #[doc = " The pairing slot."]
                pub const LINK_ID: &str = #link;
                #[doc = " The pairing's name."]
                pub const PAIRING_NAME: &str = #pairing;
                #[doc = " The pairing's tag."]
                pub const PAIRING_TAG: &str = #tag;

                #accessors
                #body
            }
        }
    }
}

/// A slot's accessors, in the slot's module and each of its topics':
/// `paired`/`wait_paired` (a participant), `sources`/`source` (an
/// observer).
fn slot_accessors(p: &ResolvedPairing) -> TokenStream {
    let link = &p.slot.link_id;
    if p.slot.observer {
        let one = match p.slot.cardinality {
            Cardinality::One => quote! {
                #[doc = " The slot's one source."]
                pub fn source(
                    node_runner: &::peppy::codegen::NodeRunner,
                ) -> ::peppy::codegen::Result<::peppy::codegen::ObservedSource> {
                    ::peppy::codegen::observed_source(node_runner, #link)?.ok_or_else(|| {
                        ::peppy::codegen::Error::Undeclared(::std::format!("a source of observer slot `{}`", #link))
                    })
                }
            },
            _ => TokenStream::new(),
        };
        quote! {
            #one
            #[doc = " The slot's sources, in link order."]
            pub fn sources(
                node_runner: &::peppy::codegen::NodeRunner,
            ) -> ::peppy::codegen::Result<::std::vec::Vec<::peppy::codegen::ObservedSource>> {
                ::peppy::codegen::observed_sources(node_runner, #link)
            }
        }
    } else {
        quote! {
            #[doc = " The peer, while the slot is paired."]
            pub fn paired(
                node_runner: &::peppy::codegen::NodeRunner,
            ) -> ::peppy::codegen::Result<::core::option::Option<::peppy::codegen::PeerInfo>> {
                ::peppy::codegen::paired(node_runner, #link)
            }

            #[doc = " Waits until the slot is paired; `Error::ShuttingDown` once the node stops."]
            pub async fn wait_paired(
                node_runner: &::peppy::codegen::NodeRunner,
            ) -> ::peppy::codegen::Result<::peppy::codegen::PeerInfo> {
                ::peppy::codegen::wait_paired(node_runner, #link).await
            }
        }
    }
}
