"""`ProducerRef`: which producer a message came from, or a request goes
to, as the peppylib node API names it."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ProducerRef:
    """One producer instance: the launch (core node) that started it and
    its instance id. Instance ids are unique in a stack, so `instance_id`
    alone names the producer; `core_node` says where it runs."""

    core_node: str
    instance_id: str

    def __str__(self) -> str:
        return self.instance_id
