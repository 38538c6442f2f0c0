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
        let emitted = p.emitted.iter().map(|t| (t, true));
        for (t, sends) in emitted.chain(p.consumed.iter().map(|t| (t, false))) {
            if names.claim(
                NameKind::module_of(self.node.node.api),
                &t.topic.decl.name,
                &what(t),
                &t.loc,
                &mut self.diags,
            ) {
                topics.extend(self.paired_topic(p, t, sends));
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
                ) -> ::peppy::codegen::Result<::peppy::codegen::TopicPublisher> {
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
        let vec_sources = quote! {
            #[doc = " The slot's sources, in link order."]
            pub fn sources(
                node_runner: &::peppy::codegen::NodeRunner,
            ) -> ::peppy::codegen::Result<::std::vec::Vec<::peppy::codegen::ObservedSource>> {
                ::peppy::codegen::observed_sources(node_runner, #link)
            }
        };
        match p.slot.cardinality {
            Cardinality::One => quote! {
                #[doc = " The slot's one source."]
                pub fn source(
                    node_runner: &::peppy::codegen::NodeRunner,
                ) -> ::peppy::codegen::Result<::peppy::codegen::ObservedSource> {
                    ::peppy::codegen::observed_source(node_runner, #link)?.ok_or_else(|| {
                        ::peppy::codegen::Error::Undeclared(::std::format!("a source of observer slot `{}`", #link))
                    })
                }

                #vec_sources
            },
            Cardinality::ZeroOrOne => quote! {
                #[doc = " The slot's source, `None` when it watches none."]
                pub fn source(
                    node_runner: &::peppy::codegen::NodeRunner,
                ) -> ::peppy::codegen::Result<::core::option::Option<::peppy::codegen::ObservedSource>> {
                    ::peppy::codegen::observed_source(node_runner, #link)
                }

                #vec_sources
            },
            Cardinality::OneOrMore => quote! {
                #[doc = " The slot's sources, in link order: never empty (`first()` always has one)."]
                pub fn sources(
                    node_runner: &::peppy::codegen::NodeRunner,
                ) -> ::peppy::codegen::Result<::peppy::codegen::NonEmptyObservedSources> {
                    ::peppy::codegen::non_empty_observed_sources(node_runner, #link)
                }
            },
            Cardinality::ZeroOrMore => vec_sources,
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

/// The pairing slots' part of the `mock` module.
#[derive(Default)]
pub(crate) struct PairingMocks {
    /// The `pairings` and `observed` modules and their structs.
    pub(crate) items: TokenStream,
    /// `Mocks`' fields.
    pub(crate) fields: TokenStream,
    /// How `Mocks::from_set` fills them.
    pub(crate) takes: TokenStream,
    /// The `PairingSlotSpec` of every slot, for the harness.
    pub(crate) specs: Vec<TokenStream>,
}

impl Gen<'_> {
    /// `mock::pairings::<link_id>` (a mock peer per participant slot) and
    /// `mock::observed::<link_id>` (mock sources per observer slot).
    pub(crate) fn pairing_mocks(&mut self) -> PairingMocks {
        let node = self.node;
        let mut out = PairingMocks::default();
        if node.pairings.is_empty() {
            return out;
        }
        let (mut peers, mut sources) = (TokenStream::new(), TokenStream::new());
        let (mut peer_fields, mut source_fields) = (TokenStream::new(), TokenStream::new());
        let (mut peer_takes, mut source_takes) = (TokenStream::new(), TokenStream::new());
        for p in &node.pairings {
            let slot = &p.slot;
            let link_id = &slot.link_id;
            let link = ident(link_id);
            let group = if slot.observer {
                quote!(observed)
            } else {
                quote!(pairings)
            };
            let mut uses = TokenStream::new();
            let mut members = TokenStream::new();
            let mut builds = TokenStream::new();
            let (mut consumed, mut emitted) = (Vec::new(), Vec::new());
            for (t, emits) in p
                .consumed
                .iter()
                .map(|t| (t, false))
                .chain(p.emitted.iter().map(|t| (t, true)))
            {
                let id = ident(&t.topic.decl.name);
                let mock_type = if emits {
                    quote! {
                        #[doc = " The mock's reader of what the node sends on this topic."]
                        pub type Subscription = ::peppy::testing::PairTopicReader<Message>;
                    }
                } else {
                    quote! {
                        #[doc = " The mock's publisher of this topic to the node."]
                        pub type Publisher = ::peppy::testing::PairTopicMock<Message>;
                    }
                };
                uses.extend(quote! {
                    #[doc = " The topic's types (those of the node's `paired_topics` module) and its mock's."]
                    pub mod #id {
                        pub use super::super::super::super::paired_topics::#link::#id::*;
                        #mock_type
                    }
                });
                if emits {
                    members.extend(quote! {
                        #[doc = " What the node sends the mock on this topic."]
                        pub #id: #id::Subscription,
                    });
                    builds.extend(quote!(#id: mock.reader(&#id::SPEC),));
                    emitted.push(quote!(&#id::SPEC));
                } else {
                    members.extend(quote! {
                        #[doc = " Publishes this topic to the node."]
                        pub #id: #id::Publisher,
                    });
                    builds.extend(quote!(#id: mock.publisher(&#id::SPEC)?,));
                    consumed.push(quote!(&#id::SPEC));
                }
            }
            let doc = if slot.observer {
                format!(
                    "A mock source of observer slot `{link_id}`: a node playing role `{}` through slot `mock_source`.",
                    slot.role
                )
            } else {
                format!(
                    "The mock peer of pairing slot `{link_id}`: a node playing role `{}` through slot `mock_peer`, paired with the node before setup runs.",
                    slot.counterpart
                )
            };
            let doc = crate::docs::Doc::new(doc);
            let instance = peppy_schema::names::mock_instance_id(link_id, None);
            let (pairing_name, pairing_tag) = (&slot.pairing.name, &slot.pairing.tag);
            let identity = if slot.observer {
                quote! {
                    #[doc = " The slot of the mock sources (the role the node watches)."]
                    pub const SOURCE_LINK_ID: &str = ::peppy::testing::MOCK_SOURCE_SLOT;

                    #[doc = " The slot's mock source as the node's `source` names it."]
                    pub fn source() -> ::peppy::codegen::ObservedSource {
                        source_for(MOCK_INSTANCE_ID)
                    }

                    #[doc = " The mock source of instance id `instance_id` (a slot of several sources: `mock-<link_id>-<n>`, n from 0)."]
                    pub fn source_for(instance_id: &str) -> ::peppy::codegen::ObservedSource {
                        ::peppy::codegen::ObservedSource {
                            producer: ::peppy::codegen::ProducerRef::new(MOCK_CORE_NODE, instance_id),
                            source_link_id: ::std::string::ToString::to_string(SOURCE_LINK_ID),
                        }
                    }
                }
            } else {
                quote! {
                    #[doc = " The slot of the mock peer."]
                    pub const PEER_LINK_ID: &str = ::peppy::testing::MOCK_PEER_SLOT;

                    #[doc = " The mock peer as the node's `paired` names it."]
                    pub fn peer_info() -> ::peppy::codegen::PeerInfo {
                        ::peppy::codegen::PeerInfo {
                            producer: ::peppy::codegen::ProducerRef::new(MOCK_CORE_NODE, MOCK_INSTANCE_ID),
                            peer_link_id: ::std::string::ToString::to_string(PEER_LINK_ID),
                        }
                    }
                }
            };
            let module = quote! {
                #doc
                pub mod #link {
                    #[doc = " The node's slot this mock plays against."]
                    pub const LINK_ID: &str = #link_id;
                    #[doc = " The pairing's name."]
                    pub const PAIRING_NAME: &str = #pairing_name;
                    #[doc = " The pairing's tag."]
                    pub const PAIRING_TAG: &str = #pairing_tag;
                    #[doc = " The core node of the harness's mocks."]
                    pub const MOCK_CORE_NODE: &str = ::peppy::testing::MOCK_CORE;
                    #[doc = " The mock's instance id."]
                    pub const MOCK_INSTANCE_ID: &str = #instance;

                    #identity

                    #uses

                    #[doc = " The slot's topics, for the harness."]
                    pub(crate) static PAIRING: ::peppy::testing::PairingSlotSpec = ::peppy::testing::PairingSlotSpec {
                        link_id: #link_id,
                        consumed: &[#(#consumed),*],
                        emitted: &[#(#emitted),*],
                    };

                    #doc
                    pub struct Mock {
                        #members
                        _mock: ::peppy::testing::PairMock,
                    }

                    impl ::core::fmt::Debug for Mock {
                        fn fmt(&self, f: &mut ::core::fmt::Formatter<'_>) -> ::core::fmt::Result {
                            ::core::fmt::Debug::fmt(&self._mock, f)
                        }
                    }

                    impl Mock {
                        pub(crate) fn new(mock: ::peppy::testing::PairMock) -> ::peppy::codegen::Result<Mock> {
                            ::core::result::Result::Ok(Mock { #builds _mock: mock })
                        }

                        #[doc = " The mock as the node's `paired` names it."]
                        pub fn peer_info(&self) -> ::peppy::codegen::PeerInfo {
                            self._mock.peer_info()
                        }

                        #[doc = " The mock instance."]
                        pub fn producer_ref(&self) -> ::peppy::codegen::ProducerRef {
                            self._mock.producer_ref()
                        }

                        #[doc = " The mock's instance id."]
                        pub fn instance_id(&self) -> &str {
                            self._mock.instance_id()
                        }

                        #[doc = " Stops the mock as its process dying would. The stop begins at once (`mock.stop();`); awaiting it waits for its end."]
                        pub fn stop(&self) -> ::peppy::testing::Stopping {
                            self._mock.stop()
                        }

                        #[doc = " The untyped mock."]
                        pub fn inner(&self) -> &::peppy::testing::PairMock {
                            &self._mock
                        }
                    }
                }
            };
            let (ty, take) = if slot.observer {
                match slot.cardinality {
                    Cardinality::One => (
                        quote!(#group::#link::Mock),
                        quote!(#group::#link::Mock::new(mocks.into_iter().next().ok_or_else(|| {
                            ::peppy::codegen::Error::Testing(::std::format!("observer slot `{}` has no mock", #link_id))
                        })?)?),
                    ),
                    Cardinality::ZeroOrOne => (
                        quote!(::core::option::Option<#group::#link::Mock>),
                        quote!(mocks.into_iter().next().map(#group::#link::Mock::new).transpose()?),
                    ),
                    Cardinality::OneOrMore | Cardinality::ZeroOrMore => (
                        quote!(::std::vec::Vec<#group::#link::Mock>),
                        quote!(mocks.into_iter().map(#group::#link::Mock::new).collect::<::peppy::codegen::Result<_>>()?),
                    ),
                }
            } else {
                (
                    quote!(#group::#link::Mock),
                    quote!(#group::#link::Mock::new(mocks.into_iter().next().ok_or_else(|| {
                        ::peppy::codegen::Error::Testing(::std::format!("pairing slot `{}` has no mock", #link_id))
                    })?)?),
                )
            };
            let field_doc = crate::docs::Doc::new(format!("The mock(s) of slot `{link_id}`."));
            let field = quote! {
                #field_doc
                pub #link: #ty,
            };
            let take = quote! {
                #link: {
                    let mocks = set.take_pairing(#link_id);
                    #take
                },
            };
            out.specs.push(quote!(&#group::#link::PAIRING));
            if slot.observer {
                sources.extend(module);
                source_fields.extend(field);
                source_takes.extend(take);
            } else {
                peers.extend(module);
                peer_fields.extend(field);
                peer_takes.extend(take);
            }
        }
        let specs = &out.specs;
        out.items = quote! {
            #[doc = " The mock peers of the node's pairing slots, by link_id."]
            #[derive(Debug)]
            pub struct Pairings {
                #peer_fields
            }

            #[doc = " The mock sources of the node's observer slots, by link_id: one `Mock` for a `one` slot, an `Option` for `zero_or_one`, a `Vec` for list slots."]
            #[derive(Debug)]
            pub struct Observed {
                #source_fields
            }

            #[doc = " One module per participant slot."]
            pub mod pairings {
                #peers
            }

            #[doc = " One module per observer slot."]
            pub mod observed {
                #sources
            }

            #[doc = " Every pairing slot's topics, for the harness."]
            pub(crate) static PAIRINGS: &[&::peppy::testing::PairingSlotSpec] = &[#(#specs),*];
        };
        out.fields = quote! {
            #[doc = " By pairing slot: the mock peers."]
            pub pairings: Pairings,
            #[doc = " By observer slot: the mock sources."]
            pub observed: Observed,
        };
        out.takes = quote! {
            pairings: Pairings { #peer_takes },
            observed: Observed { #source_takes },
        };
        out
    }
}
