"""The server side of a request, one way for every queryable (services and
action goals): read the caller's header, answer a probe and a request in
another format, ack, and queue without ever blocking Zenoh's thread (a
full queue answers busy)."""

from __future__ import annotations

import logging
from typing import Any, NamedTuple, Optional

from . import attachment
from .attachment import QueryHeader, QueryKind, ReplyStatus
from .bridge import Mailbox
from .formats import Format

log = logging.getLogger("peppy")

QUEUE_CAPACITY = 64
"""Requests (or goals) queued for the node's code before the server answers busy."""


def reply(query: Any, key: str, status: ReplyStatus, fingerprint: int, payload: bytes, entry: str) -> None:
    """Replies with a status; a reply that cannot be sent (the caller gave up) is only logged."""
    try:
        query.reply(key, payload, attachment=attachment.reply(status, fingerprint))
    except Exception as e:  # the query may be finished or the session closed
        log.debug("`%s`: reply failed: %s", entry, e)


def finish(query: Any) -> None:
    """Ends the query, so the caller's request completes without waiting for its timeout."""
    try:
        query.drop()
    except Exception:
        pass


def payload_of(query: Any) -> bytes:
    """The query's payload bytes (empty when it has none)."""
    p = query.payload
    return b"" if p is None else p.to_bytes()


def admit(query: Any, key: str, entry: str, request: Format, fingerprint: int) -> Optional[QueryHeader]:
    """The header of a request to handle; None when the query was answered
    (probe: present; another request format: format mismatch with this
    server's text) or dropped (no valid header). Status replies carry `fingerprint`."""
    att = query.attachment
    header = QueryHeader.decode(None if att is None else att.to_bytes())
    if header is None:
        log.debug("`%s`: dropping a query without a valid peppy attachment", entry)
        finish(query)
        return None
    if header.kind == QueryKind.PROBE:
        reply(query, key, ReplyStatus.PRESENT, fingerprint, b"", entry)
        finish(query)
        return None
    if header.fingerprint != request.fingerprint:
        log.warning(
            "`%s`: refusing a request from `%s` whose format differs from this server's", entry, header.instance
        )
        reply(query, key, ReplyStatus.FORMAT_MISMATCH, fingerprint, request.canonical.encode("utf-8"), entry)
        finish(query)
        return None
    return header


class Pending(NamedTuple):
    """A request waiting for the node's code: the query, its header, its body."""

    query: Any
    header: QueryHeader
    payload: bytes


def enqueue(mailbox: Mailbox, item: Pending, key: str, fingerprint: int, entry: str, queued: str) -> None:
    """Acks a request and queues it; a full queue answers busy."""
    reply(item.query, key, ReplyStatus.ACK, fingerprint, b"", entry)
    if mailbox.offer(item, QUEUE_CAPACITY):
        return
    if mailbox.closed:
        log.debug("`%s`: the node is stopping; dropping a request", entry)
    else:
        log.warning("`%s`: %s queue full; answering busy", entry, queued)
        reply(
            item.query,
            key,
            ReplyStatus.HANDLER_ERROR,
            fingerprint,
            f"server busy: too many queued {queued}".encode("utf-8"),
            entry,
        )
    finish(item.query)
