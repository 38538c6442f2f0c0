//! `exposed_actions::<action>` and `consumed_actions::<link_id>_<action>`:
//! typed veneers over the runtime's goal server (`next_goal`,
//! `GoalContext`) and goal client (`send_goal`, `GoalClient`).

use peppy_schema::{ActionDecl, MessageFormat, Provided, ResolvedCall};
use proc_macro2::TokenStream;
use quote::quote;

use crate::generate::{Gen, RESERVED_ARGS, owner};
use crate::naming::{Names, type_prefix};
use crate::types::{Structs, args, format_spec, many_args_allow, snake_allow};

/// The nested-type prefixes of an action's formats (SPEC 4): `Goal`,
/// `<Action>Feedback`, `<Action>Result`.
pub(crate) struct Prefixes {
    pub(crate) goal: String,
    pub(crate) feedback: String,
    pub(crate) result: String,
}

pub(crate) fn prefixes(action: &str) -> Prefixes {
    let camel = type_prefix(action);
    Prefixes {
        goal: "Goal".to_string(),
        feedback: format!("{camel}Feedback"),
        result: format!("{camel}Result"),
    }
}

fn fields_of(format: Option<&MessageFormat>) -> &[peppy_schema::Field] {
    format.map(|f| f.fields.as_slice()).unwrap_or(&[])
}

/// `name(self|&self, fields...)` plumbing: parameters, the struct literal
/// initialisers and the lint allowances for a method taking `fields`.
struct Method {
    params: Vec<TokenStream>,
    inits: Vec<TokenStream>,
    allows: TokenStream,
}

fn method(prefix: &str, fields: &[peppy_schema::Field]) -> Method {
    let a = args(prefix, fields, RESERVED_ARGS);
    let mut allows = snake_allow(fields);
    allows.extend(many_args_allow(fields.len() + 1));
    Method {
        params: a.params,
        inits: a.inits,
        allows,
    }
}

impl Gen<'_> {
    /// `exposed_actions::<action>`: `GoalRequest`, `GoalResponse`,
    /// `ActionHandle` (`expose`, `handle_goal_next_request`) and
    /// `GoalContext` (`request`, `goal_id`, `cancel_signal`, `is_cancelled`,
    /// `publish_feedback`, `complete`, `complete_cancelled`).
    ///
    /// Long on purpose: most of it is one `quote!` template, kept whole so
    /// the generated module reads top to bottom as users see it.
    pub(crate) fn exposed_action(&mut self, p: &Provided<ActionDecl>) -> TokenStream {
        let decl = &p.decl;
        let name = &decl.name;
        let pre = prefixes(name);
        let feedback_type = pre.feedback.clone();
        let result_type = pre.result.clone();
        let mut fixed = vec![
            "GoalRequest",
            "GoalResponse",
            "GoalDecision",
            "ActionHandle",
            "GoalContext",
            result_type.as_str(),
        ];
        if decl.goal.is_some() {
            fixed.push("GoalRequestData");
        }
        if decl.feedback.is_some() {
            fixed.push(feedback_type.as_str());
        }
        let mut names = Names::with_fixed(&fixed);
        let mut structs = Structs {
            names: &mut names,
            diags: &mut self.diags,
            out: TokenStream::new(),
        };
        if let Some(goal) = &decl.goal {
            let doc = format!("The goal data of action `{name}`.");
            structs.message("GoalRequestData", &pre.goal, Some(goal), &doc);
        }
        if let Some(fb) = &decl.feedback {
            let doc = format!("A feedback message of action `{name}`.");
            structs.message(&feedback_type, &pre.feedback, Some(&fb.format), &doc);
        }
        let doc = format!("The result of action `{name}`.");
        structs.message(&result_type, &pre.result, decl.result.as_ref(), &doc);
        let types = structs.out;

        let feedback_id = crate::naming::ident(&feedback_type);
        let result_id = crate::naming::ident(&result_type);
        let (data_field, data_type, data_init) = match &decl.goal {
            Some(_) => (
                quote! {
                    #[doc = " The goal data."]
                    pub data: GoalRequestData,
                },
                quote!(GoalRequestData),
                quote!(data: incoming.data.clone(),),
            ),
            None => (quote!(), quote!(()), quote!()),
        };
        let publish = match &decl.feedback {
            Some(fb) => {
                let m = method(&pre.feedback, &fb.format.fields);
                let (params, inits, allows) = (&m.params, &m.inits, &m.allows);
                quote! {
                    #[doc = " Publishes one feedback message on this goal's stream, the fields in declaration order."]
                    #allows
                    pub async fn publish_feedback(&self, #(#params),*) -> ::peppy::codegen::Result<()> {
                        let message = #feedback_id { #(#inits),* };
                        self.inner.publish_feedback(&message).await
                    }
                }
            }
            None => quote!(),
        };
        let result_fields = fields_of(decl.result.as_ref());
        let m = method(&pre.result, result_fields);
        let (params, inits, allows) = (&m.params, &m.inits, &m.allows);
        let owner = owner(&p.origin, true);
        let goal_format = format_spec(decl.goal.as_ref());
        let feedback_format = format_spec(decl.feedback.as_ref().map(|f| &f.format));
        let result_format = format_spec(decl.result.as_ref());
        let goal_doc = crate::docs::Doc::new(format!(
            "A goal sent to action `{name}`, with the caller's identity{}.",
            if decl.goal.is_some() {
                " and its data"
            } else {
                " (the action takes no goal data)"
            }
        ));
        // The peppylib API decides with `GoalDecision` (the action's own
        // when it declares a goal response); the emit API with `GoalResponse`.
        // Both hand the decider the request by reference, as PeppyOS does.
        let declared = decl.goal_response.as_ref();
        let mut decision_types = TokenStream::new();
        if let Some(format) = declared {
            let mut structs = Structs {
                names: &mut names,
                diags: &mut self.diags,
                out: TokenStream::new(),
            };
            let doc =
                format!("The goal response action `{name}` declares: data sent with a decision.");
            structs.message("GoalResponse", "GoalResponse", Some(format), &doc);
            decision_types = structs.out;
        }
        let (decision_use, decider_bound, accepted, rejected, reason, accept_call, reject_call) =
            match (self.peppylib(), declared.is_some()) {
                (true, true) => (
                    quote! {
                        #decision_types

                        #[doc = " The server's decision on a goal: `GoalDecision::accept(response)` or `GoalDecision::reject(reason)`; construct `GoalDecision::Reject { reason, response }` to send a response with a rejection."]
                        #[derive(::core::fmt::Debug, ::core::clone::Clone, ::core::cmp::PartialEq)]
                        pub enum GoalDecision {
                            #[doc = " Accept the goal, answering with the declared response."]
                            Accept(GoalResponse),
                            #[doc = " Reject the goal."]
                            Reject {
                                #[doc = " Why, as the caller reads it."]
                                reason: ::core::option::Option<::std::string::String>,
                                #[doc = " A response to send with the rejection."]
                                response: ::core::option::Option<GoalResponse>,
                            },
                        }

                        impl GoalDecision {
                            #[doc = " Accepts the goal with its declared response."]
                            pub fn accept(response: GoalResponse) -> Self {
                                GoalDecision::Accept(response)
                            }

                            #[doc = " Rejects the goal with a reason and no response."]
                            pub fn reject(reason: impl ::core::convert::Into<::std::string::String>) -> Self {
                                GoalDecision::Reject {
                                    reason: ::core::option::Option::Some(reason.into()),
                                    response: ::core::option::Option::None,
                                }
                            }
                        }
                    },
                    quote!(::core::ops::FnMut(&GoalRequest) -> ::peppy::codegen::Result<GoalDecision>),
                    quote!(GoalDecision::Accept(response)),
                    quote!(GoalDecision::Reject { reason, response }),
                    quote!(reason),
                    quote!(incoming.accept_with(::peppy::codegen::to_bytes(&response))),
                    quote!(
                        incoming.reject_with(
                            reason,
                            response
                                .map(|r| ::peppy::codegen::to_bytes(&r))
                                .unwrap_or_default()
                        )
                    ),
                ),
                (true, false) => (
                    quote! {
                        #[doc = " The server's decision on a goal: `GoalDecision::accept()` or `GoalDecision::reject(reason)`."]
                        pub use ::peppy::codegen::GoalDecision;
                    },
                    quote!(::core::ops::FnMut(&GoalRequest) -> ::peppy::codegen::Result<GoalDecision>),
                    quote!(GoalDecision::Accept),
                    quote!(GoalDecision::Reject { reason }),
                    quote!(reason),
                    quote!(incoming.accept()),
                    quote!(incoming.reject_with(reason, ::std::vec::Vec::new())),
                ),
                (false, _) => (
                    quote! {
                        #[doc = " The server's decision on a goal: `GoalResponse::accept()` or `GoalResponse::reject(reason)`."]
                        pub use ::peppy::codegen::GoalResponse;
                    },
                    quote!(::core::ops::FnMut(&GoalRequest) -> ::peppy::codegen::Result<GoalResponse>),
                    quote!(GoalResponse { accepted: true, .. }),
                    quote!(GoalResponse { error_message, .. }),
                    quote!(error_message),
                    quote!(incoming.accept()),
                    quote!(incoming.reject_with(error_message, ::std::vec::Vec::new())),
                ),
            };
        let _ = reason;
        quote! {
            #types

            #decision_use

            #goal_doc
            #[derive(::core::fmt::Debug, ::core::clone::Clone, ::core::cmp::PartialEq)]
            pub struct GoalRequest {
                #[doc = " The caller's instance id."]
                pub instance_id: ::std::string::String,
                #[doc = " The launch (core node) that started the caller."]
                pub core_node: ::std::string::String,
                #data_field
            }

            #[doc = " What the runtime knows about this action."]
            pub(crate) static SPEC: ::peppy::codegen::ActionSpec = ::peppy::codegen::ActionSpec {
                owner: #owner,
                name: #name,
                goal: #goal_format,
                feedback: #feedback_format,
                result: #result_format,
            };

            #[doc = " This node's server of the action. Its goal, cancel and result services live as long as the node; several goals may run at once. The handle owns what it needs (it does not borrow the runner), so it can move into a spawned task."]
            #[derive(::core::fmt::Debug)]
            pub struct ActionHandle {
                server: ::peppy::codegen::GoalServer,
            }

            impl ActionHandle {
                #[doc = " The action's server on this node. `&runner` may be an `&Arc<NodeRunner>`; the handle keeps no borrow of it."]
                pub async fn expose(node_runner: &::peppy::codegen::NodeRunner) -> ::peppy::codegen::Result<Self> {
                    let server = ::peppy::codegen::GoalServer::new(node_runner, &SPEC)?;
                    ::core::result::Result::Ok(ActionHandle { server })
                }

                #[doc = " Waits for the next goal and lets `decider` accept or reject it. Rejected goals are answered and skipped; an accepted goal is returned to be worked on. When `decider` fails, the goal is rejected with its error as the reason and the error is returned. `None` once the node stops: at once if it was waiting, after a short pause if called on an already stopped node, so a loop that ignores the result parks instead of spinning."]
                pub async fn handle_goal_next_request<F>(
                    &mut self,
                    #[allow(unused_mut)] mut decider: F,
                ) -> ::peppy::codegen::Result<::core::option::Option<GoalContext>>
                where
                    F: #decider_bound,
                {
                    loop {
                        let incoming = match self.server.next::<#data_type>().await {
                            ::core::result::Result::Ok(incoming) => incoming,
                            ::core::result::Result::Err(::peppy::codegen::Error::ShuttingDown) => {
                                return ::core::result::Result::Ok(::core::option::Option::None);
                            }
                            ::core::result::Result::Err(e) => return ::core::result::Result::Err(e),
                        };
                        let request = GoalRequest {
                            instance_id: incoming.caller.instance_id.clone(),
                            core_node: incoming.caller.core_node.clone(),
                            #data_init
                        };
                        match decider(&request) {
                            ::core::result::Result::Ok(#accepted) => {
                                let inner = #accept_call?;
                                return ::core::result::Result::Ok(::core::option::Option::Some(GoalContext { inner, request }));
                            }
                            ::core::result::Result::Ok(#rejected) => {
                                #reject_call?;
                            }
                            ::core::result::Result::Err(e) => {
                                // The caller hears why, and the node's
                                // accept loop gets its own error back.
                                let _ = incoming.reject(::std::string::ToString::to_string(&e));
                                return ::core::result::Result::Err(e);
                            }
                        }
                    }
                }
            }

            #[doc = " An accepted goal being worked on. Finish it with `complete` or `complete_cancelled`; dropping it unfinished reports `Abandoned` to the caller."]
            #[derive(::core::fmt::Debug)]
            pub struct GoalContext {
                inner: ::peppy::codegen::GoalContext,
                request: GoalRequest,
            }

            impl GoalContext {
                #[doc = " The goal as the caller sent it."]
                pub fn request(&self) -> &GoalRequest {
                    &self.request
                }

                #[doc = " The goal's id."]
                pub fn goal_id(&self) -> &str {
                    self.inner.goal_id()
                }

                #[doc = " Resolves when the caller asks to cancel the goal."]
                pub async fn cancel_signal(&self) {
                    self.inner.cancel_signal().await
                }

                #[doc = " Whether the caller asked to cancel the goal."]
                pub fn is_cancelled(&self) -> bool {
                    self.inner.is_cancelled()
                }

                #publish

                #[doc = " Finishes the goal successfully with its result, the fields in declaration order."]
                #allows
                pub async fn complete(&self, #(#params),*) -> ::peppy::codegen::Result<()> {
                    let result = #result_id { #(#inits),* };
                    self.inner.complete(&result)
                }

                #[doc = " Finishes the goal as cancelled, with a (partial) result."]
                #allows
                pub async fn complete_cancelled(&self, #(#params),*) -> ::peppy::codegen::Result<()> {
                    let result = #result_id { #(#inits),* };
                    self.inner.complete_cancelled(&result)
                }
            }
        }
    }

    /// `consumed_actions::<link_id>_<action>`: `GoalRequest`,
    /// `ActionHandle` (`fire_goal`, `data`, `on_next_feedback_message`,
    /// `get_result`, `cancel_goal`), `ResultResponse` / `ResultOutcome`,
    /// `CancelResponse` / `CancelState`.
    ///
    /// Long on purpose: most of it is one `quote!` template, kept whole so
    /// the generated module reads top to bottom as users see it.
    pub(crate) fn consumed_action(&mut self, c: &ResolvedCall<ActionDecl>) -> TokenStream {
        let decl = &c.decl;
        let name = &decl.name;
        let pre = prefixes(name);
        let mut fixed = vec![
            "GoalResponseData",
            "ResultOutcome",
            "ResultResponse",
            "CancelState",
            "CancelResponse",
            "ActionHandle",
        ];
        if decl.goal.is_some() {
            fixed.push("GoalRequest");
        }
        if decl.feedback.is_some() {
            fixed.push("FeedbackMessage");
        }
        if decl.result.is_some() {
            fixed.push("ResultResponseData");
        }
        let declared = decl.goal_response.as_ref();
        let mut names = Names::with_fixed(&fixed);
        let mut structs = Structs {
            names: &mut names,
            diags: &mut self.diags,
            out: TokenStream::new(),
        };
        if let Some(goal) = &decl.goal {
            let doc = format!("A goal for action `{name}`; build it with `GoalRequest::new`.");
            structs.message("GoalRequest", &pre.goal, Some(goal), &doc);
        }
        if let Some(fb) = &decl.feedback {
            let doc = format!("A feedback message of action `{name}`.");
            structs.message("FeedbackMessage", &pre.feedback, Some(&fb.format), &doc);
        }
        if let Some(result) = &decl.result {
            let doc = format!("The result data of action `{name}`.");
            structs.message("ResultResponseData", &pre.result, Some(result), &doc);
        }
        if let Some(response) = declared {
            let doc = format!(
                "The goal response action `{name}` declares: data the server sends with its decision."
            );
            structs.message("GoalResponseData", "GoalResponseData", Some(response), &doc);
        }
        let types = structs.out;
        let mut constructors =
            data_constructor("ResultResponseData", &pre.result, decl.result.as_ref());
        if let Some(response) = declared {
            constructors.extend(data_constructor(
                "GoalResponseData",
                "GoalResponseData",
                Some(response),
            ));
        }

        let constructor = goal_constructor(&pre.goal, decl.goal.as_ref());
        let (goal_param, goal_ref) = match &decl.goal {
            Some(_) => (quote!(request: GoalRequest,), quote!(&request)),
            None => (quote!(), quote!(&())),
        };
        let feedback = match &decl.feedback {
            Some(_) => quote! {
                #[doc = " The next feedback message of this goal; `Error::ActionFeedbackChannelClosed` once the goal is terminal and every feedback message was read; `Error::ShuttingDown` once this node stops."]
                pub async fn on_next_feedback_message(&mut self) -> ::peppy::codegen::Result<FeedbackMessage> {
                    self.inner.next_feedback::<FeedbackMessage>().await
                }
            },
            None => quote!(),
        };
        let (outcome, result_type, completed, cancelled) = result_outcome(decl.result.is_some());
        let link_id = &c.slot.link_id;
        let owner = owner(&c.origin, false);
        let goal_format = format_spec(decl.goal.as_ref());
        let feedback_format = format_spec(decl.feedback.as_ref().map(|f| &f.format));
        let result_format = format_spec(decl.result.as_ref());
        let (response_use, handle_doc, handle_fields, fire_doc, target_param, send, decision) =
            if self.peppylib() {
                (
                    quote!(),
                    quote!(#[doc = " A goal sent to the action's server. `accepted` says whether it was accepted (and `reason` why not)."]),
                    {
                        let data = declared.map(|_| {
                            quote! {
                                #[doc = " The goal response the server sent with its decision (`None` when a rejection carried none)."]
                                pub data: ::core::option::Option<GoalResponseData>,
                            }
                        });
                        quote! {
                            #[doc = " Whether the server accepted the goal."]
                            pub accepted: bool,
                            #[doc = " The server's reason when it rejected the goal."]
                            pub reason: ::core::option::Option<::std::string::String>,
                            #data
                        }
                    },
                    quote!(#[doc = " Sends a goal to `target`, one of the producers bound to the action's slot (`bound_producer` / `bound_producers`), and waits at most `timeout` for the decision; returns after a rejection too (check `accepted`). `TargetNotBound` for any other target, before anything is sent. The feedback stream is subscribed before the goal is sent, so no feedback is missed. `feedback_qos` is accepted for compatibility: feedback travels with the server's declared QoS."]),
                    quote!(target: &::peppy::codegen::ProducerRef,),
                    quote!(::peppy::codegen::send_goal_to(node_runner, &SPEC, target, timeout, #goal_ref)),
                    match declared {
                        Some(_) => quote! {
                            let accepted = inner.accepted;
                            let reason = inner.error_message.clone();
                            let data = inner.goal_response::<GoalResponseData>()?;
                            ::core::result::Result::Ok(ActionHandle { inner, accepted, reason, data })
                        },
                        None => quote! {
                            let accepted = inner.accepted;
                            let reason = inner.error_message.clone();
                            ::core::result::Result::Ok(ActionHandle { inner, accepted, reason })
                        },
                    },
                )
            } else {
                (
                    quote! {
                        #[doc = " The server's decision on the goal: `accepted`, and `error_message` when rejected."]
                        pub use ::peppy::codegen::GoalResponse as GoalResponseData;
                    },
                    quote!(#[doc = " A goal sent to the action's server. `data.accepted` says whether it was accepted (and `data.error_message` why not)."]),
                    quote! {
                        #[doc = " The server's decision."]
                        pub data: GoalResponseData,
                    },
                    quote!(#[doc = " Sends a goal through the slot (straight to a pinned producer, else to the first the slot accepts) and waits at most `timeout` for the decision; returns after a rejection too (check `data.accepted`). The feedback stream is subscribed before the goal is sent, so no feedback is missed. `feedback_qos` is accepted for compatibility: feedback travels with the server's declared QoS."]),
                    quote!(),
                    quote!(::peppy::codegen::send_goal(node_runner, &SPEC, timeout, #goal_ref)),
                    quote! {
                        let data = GoalResponseData::new(inner.accepted, inner.error_message.clone());
                        ::core::result::Result::Ok(ActionHandle { inner, data })
                    },
                )
            };
        quote! {
            #types

            #constructor

            #constructors

            #response_use

            #[doc = " The answer to a cancel request."]
            pub use ::peppy::codegen::CancelState;

            #outcome

            #[doc = " How the goal ended, with the server's identity."]
            #[derive(::core::fmt::Debug, ::core::clone::Clone, ::core::cmp::PartialEq)]
            pub struct ResultResponse {
                #[doc = " The server's instance id."]
                pub instance_id: ::std::string::String,
                #[doc = " The launch (core node) that started the server."]
                pub core_node: ::std::string::String,
                #[doc = " How the goal ended."]
                pub outcome: ResultOutcome,
            }

            #[doc = " The server's answer to a cancel request, with its identity."]
            #[derive(::core::fmt::Debug, ::core::clone::Clone, ::core::cmp::PartialEq)]
            pub struct CancelResponse {
                #[doc = " The server's instance id."]
                pub instance_id: ::std::string::String,
                #[doc = " The launch (core node) that started the server."]
                pub core_node: ::std::string::String,
                #[doc = " What the cancel request did."]
                pub state: CancelState,
            }

            #[doc = " What the runtime knows about this action."]
            pub(crate) static SPEC: ::peppy::codegen::ConsumedActionSpec = ::peppy::codegen::ConsumedActionSpec {
                link_id: #link_id,
                owner: #owner,
                name: #name,
                goal: #goal_format,
                feedback: #feedback_format,
                result: #result_format,
            };

            #handle_doc
            #[derive(::core::fmt::Debug)]
            pub struct ActionHandle {
                inner: ::peppy::codegen::GoalClient,
                #handle_fields
            }

            impl ActionHandle {
                #fire_doc
                pub async fn fire_goal(
                    node_runner: &::peppy::codegen::NodeRunner,
                    #target_param
                    timeout: ::core::time::Duration,
                    #goal_param
                    feedback_qos: ::peppy::codegen::QoSProfile,
                ) -> ::peppy::codegen::Result<Self> {
                    let _ = feedback_qos;
                    let inner = #send.await?;
                    #decision
                }

                #[doc = " The goal's id."]
                pub fn goal_id(&self) -> &str {
                    self.inner.goal_id()
                }

                #feedback

                #[doc = " Waits (at most `timeout`) until the goal is terminal and returns how it ended. Results stay available for 30 s after the goal ends, then `Expired`."]
                pub async fn get_result(
                    &self,
                    timeout: ::core::time::Duration,
                ) -> ::peppy::codegen::Result<ResultResponse> {
                    let outcome = match self.inner.result::<#result_type>(timeout).await? {
                        ::peppy::codegen::Outcome::Completed(data) => #completed,
                        ::peppy::codegen::Outcome::Cancelled(data) => #cancelled,
                        ::peppy::codegen::Outcome::Abandoned => ResultOutcome::Abandoned,
                        ::peppy::codegen::Outcome::Expired => ResultOutcome::Expired,
                    };
                    ::core::result::Result::Ok(ResultResponse {
                        instance_id: self.inner.instance_id.clone(),
                        core_node: self.inner.core_node.clone(),
                        outcome,
                    })
                }

                #[doc = " Asks the server to cancel the goal and waits at most `timeout` for its answer."]
                pub async fn cancel_goal(
                    &self,
                    timeout: ::core::time::Duration,
                ) -> ::peppy::codegen::Result<CancelResponse> {
                    let state = self.inner.cancel(timeout).await?;
                    ::core::result::Result::Ok(CancelResponse {
                        instance_id: self.inner.instance_id.clone(),
                        core_node: self.inner.core_node.clone(),
                        state,
                    })
                }
            }
        }
    }
}

/// `GoalRequest::new`, the constructor of a consumed action's goal from
/// its fields (nothing without goal data).
fn goal_constructor(prefix: &str, goal: Option<&MessageFormat>) -> TokenStream {
    match goal {
        Some(goal) => {
            let a = args(prefix, &goal.fields, &[]);
            let (params, inits) = (&a.params, &a.inits);
            let allows = {
                let mut t = snake_allow(&goal.fields);
                t.extend(many_args_allow(goal.fields.len()));
                t
            };
            quote! {
                impl GoalRequest {
                    #[doc = " A goal from its fields, in declaration order."]
                    #allows
                    pub fn new(#(#params),*) -> Self {
                        Self { #(#inits),* }
                    }
                }
            }
        }
        None => quote!(),
    }
}

/// `<Type>::new`, the constructor of a message struct from its fields, in
/// declaration order (nothing without a format): a test scripts a mock's
/// answers with it (`ResponseData::new(..)`, `ResultResponseData::new(..)`).
pub(crate) fn data_constructor(
    type_name: &str,
    prefix: &str,
    format: Option<&MessageFormat>,
) -> TokenStream {
    let Some(format) = format else {
        return TokenStream::new();
    };
    let a = args(prefix, &format.fields, &[]);
    let (params, inits) = (&a.params, &a.inits);
    let mut allows = snake_allow(&format.fields);
    allows.extend(many_args_allow(format.fields.len()));
    let ty = crate::naming::ident(type_name);
    quote! {
        impl #ty {
            #[doc = " A value from its fields, in declaration order."]
            #allows
            pub fn new(#(#params),*) -> Self {
                Self { #(#inits),* }
            }
        }
    }
}

/// A consumed action's `ResultOutcome` enum and the pieces that build it:
/// `(enum, result data type, completed, cancelled)`, with or without result
/// data.
fn result_outcome(has_result: bool) -> (TokenStream, TokenStream, TokenStream, TokenStream) {
    match has_result {
        true => (
            quote! {
                #[doc = " How a goal ended."]
                #[derive(::core::fmt::Debug, ::core::clone::Clone, ::core::cmp::PartialEq)]
                pub enum ResultOutcome {
                    #[doc = " Finished with a result."]
                    Completed(ResultResponseData),
                    #[doc = " Cancelled, with a (partial) result."]
                    Cancelled(ResultResponseData),
                    #[doc = " The server dropped the goal without a result."]
                    Abandoned,
                    #[doc = " The result was not fetched within the server's retention period (30 s)."]
                    Expired,
                }
            },
            quote!(ResultResponseData),
            quote!(ResultOutcome::Completed(data)),
            quote!(ResultOutcome::Cancelled(data)),
        ),
        false => (
            quote! {
                #[doc = " How a goal ended (the action has no result data)."]
                #[derive(::core::fmt::Debug, ::core::clone::Clone, ::core::marker::Copy, ::core::cmp::PartialEq, ::core::cmp::Eq)]
                pub enum ResultOutcome {
                    #[doc = " Finished."]
                    Completed,
                    #[doc = " Cancelled."]
                    Cancelled,
                    #[doc = " The server dropped the goal without a result."]
                    Abandoned,
                    #[doc = " The result was not fetched within the server's retention period (30 s)."]
                    Expired,
                }
            },
            quote!(()),
            quote!({
                let () = data;
                ResultOutcome::Completed
            }),
            quote!({
                let () = data;
                ResultOutcome::Cancelled
            }),
        ),
    }
}
