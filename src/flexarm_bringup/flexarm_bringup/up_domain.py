"""Which ROS domain ``flexarm up`` starts its graph in.

``--domain-id N`` wins: exactly N, refused only by another graph's lock on N and the namespace
(:class:`flexarm_bringup.supervisor.Graph`); a harness that reserved N for itself
passes it so. Else an exported ``ROS_DOMAIN_ID``: the domain that ``move``, ``status`` and
``collect`` of the same shell talk to, so two shells that export one id meet. It is refused, before
anything starts, when a graph of this machine runs there in the same namespace, or when another
process reserved it (:mod:`flexarm_bringup.domains`: a test run, a benchmark,
``flexarm demo``) and no flexarm graph runs there (an arm of another namespace shares its domain,
and holds its reservation). A free domain only when none is exported.

The domain used is reserved while the graph runs whenever its reservation is free, so that
whoever looks for a free domain skips it.
"""
from __future__ import annotations

import socket
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from flexarm_bringup import domains
from flexarm_bringup.running_graphs import RunningGraph

ENV = 'ROS_DOMAIN_ID'
# How the domain was chosen, as ``flexarm up`` says it.
GIVEN, EXPORTED, FREE = '--domain-id', 'exported', 'a free one: no ROS_DOMAIN_ID exported'


class DomainRefused(Exception):
    """The exported domain cannot take the graph: why, and what to do."""


@dataclass(frozen=True)
class Claim:
    """The graph's domain, how it was chosen (:data:`GIVEN`, :data:`EXPORTED` or
    :data:`FREE`) and the socket that reserves it until closed (None where another process
    holds the reservation)."""

    domain_id: int
    how: str
    reservation: socket.socket | None


def exported(environ: Mapping[str, str]) -> int | None:
    """The domain ``environ`` exports; None if unset or empty (rcl reads an empty one as
    unset); :class:`DomainRefused` if it is no domain id."""
    text = environ.get(ENV, '').strip()
    if not text:
        return None
    if not text.isdigit() or int(text) > domains.MAX_DOMAIN_ID:
        raise DomainRefused(f'{ENV}={text!r} is exported, but a ROS domain is a whole number '
                            f'0..{domains.MAX_DOMAIN_ID}: export one, or unset it for a free '
                            'domain')
    return int(text)


def claim_domain(given: int | None, environ: Mapping[str, str], namespace: str,
                 graphs: Callable[[], Sequence[RunningGraph]]) -> Claim:
    """The domain of the graph of the arm in ``namespace``; ``graphs``: the graphs running on
    this machine (:func:`flexarm_bringup.running_graphs.running_graphs`)."""
    if given is not None:
        return Claim(given, GIVEN, domains.hold(given))
    domain = exported(environ)
    if domain is None:
        free, sock = domains.first_free()
        return Claim(free, FREE, sock)
    namespace = namespace.strip('/')
    here = [g for g in graphs() if g.domain_id == domain]
    same = next((g for g in here if g.namespace == namespace), None)
    if same is not None:
        arm = f' with namespace {namespace}' if namespace else ''
        raise DomainRefused(
            f'{ENV}={domain} (exported) already runs the flexarm graph of supervisor pid '
            f'{same.supervisor_pid}{arm} (robot {same.robot}, run folder {same.run_dir or "?"}):'
            f' use that graph, stop it (flexarm down --domain-id {domain}), or export another '
            f'{ENV}')
    sock = domains.hold(domain)
    if sock is None and not here:
        raise DomainRefused(
            f'{ENV}={domain} (exported) is reserved by another process of this machine (it '
            f'holds TCP port {domains.PORT_BASE + domain}, as test runs, benchmarks and '
            f'flexarm demo reserve their domain): export another {ENV}, unset it for a free '
            f'domain, or pass --domain-id {domain} to start there all the same')
    return Claim(domain, EXPORTED, sock)

