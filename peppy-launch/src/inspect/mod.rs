//! Looking into a running stack: `node`, `topic`, `service`, `action`,
//! `graph --live`. The observer joins the stack's Zenoh network as a plain
//! session: it holds no liveliness token and serves nothing, so it never
//! fills a slot and never counts as a producer.

pub(crate) mod dynamic;
