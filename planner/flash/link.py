"""The host's end of the serial link: one request, its response, timeouts and retries.

Stop and wait (docs/protocol.md section 3): a request is resent with the same
sequence number until its response arrives or the retries run out; damaged frames,
other drivers' answers and stale responses are skipped. Every attempt's timeout is
capped (:data:`MAX_ATTEMPT_S`) and a :attr:`Link.deadline` ends all requests to a driver.
Works on any pyserial ``Serial`` (a real port, ``sim://``, a pseudo-terminal).
"""

from __future__ import annotations

import secrets
import time
from dataclasses import dataclass, field

from planner.errors import PlannerError, UsageError
from planner.flash.wire import FLAG_RESPONSE, Command, Deframer, Packet, Status, encode, parse_error

RETRIES = 4
BASE_TIMEOUT_S = 0.020
MAX_ATTEMPT_S = 10.0
"""Ceiling of one attempt's timeout [s], whatever a driver's HELLO claims (``--extra-timeout-ms`` comes on top)."""


class LinkError(PlannerError):
    """A driver did not answer (after every retry), or answered with an error status."""

    def __init__(self, message: str, status: int | None = None, detail: int = 0):
        super().__init__(message)
        self.status = status
        self.detail = detail


class DeadlineError(LinkError):
    """The driver's deadline (:attr:`Link.deadline`) passed: no more requests to it."""


class PortLost(UsageError):
    """The serial port itself failed (adapter unplugged, the far end gone): no driver can answer."""


@dataclass
class LinkStats:
    """Counters over the link's life: for progress lines and the benchmark."""

    requests: int = 0
    retries: int = 0
    bytes_sent: int = 0
    bytes_received: int = 0
    dropped_frames: int = 0
    busy_s: float = 0.0
    by_command: dict = field(default_factory=dict)


class Link:
    """Requests to drivers over ``port`` (a pyserial ``Serial``) at ``baud`` [bit/s]."""

    def __init__(self, port, baud: int = 115200, retries: int = RETRIES, extra_timeout_s: float = 0.0):
        self.port = port
        self.baud = baud
        self.retries = retries
        self.extra_timeout_s = extra_timeout_s  # added to every attempt: adapters with latency, emulated drivers
        self.deadline: float | None = None  # time.perf_counter() after which no request starts or waits
        self._seqs: dict[int, int] = {}
        self.seq = 0
        self.stats = LinkStats()
        self._deframer = Deframer()

    def line_time_s(self, n_bytes: int) -> float:
        """Seconds ``n_bytes`` take on the line (10 bits a byte: start, 8 data, stop)."""
        return n_bytes * 10 / self.baud

    def timeout_s(self, request_bytes: int, response_bytes: int, driver_s: float = 0.0) -> float:
        """Protocol section 3: 20 ms + twice the line time both ways + the driver's work, at most
        :data:`MAX_ATTEMPT_S` (+ ``extra_timeout_s``)."""
        protocol_s = BASE_TIMEOUT_S + 2 * self.line_time_s(request_bytes + response_bytes) + driver_s
        return min(protocol_s, MAX_ATTEMPT_S) + self.extra_timeout_s

    def request(self, address: int, command: Command, payload: bytes = b"", *, response_bytes: int = 80,
                driver_s: float = 0.0) -> Packet:
        """Send one request and return its (non-error) response; :class:`LinkError` otherwise."""
        # One counter per driver address, from a random start each session: a driver's cache of its
        # last request then never mistakes a new request for a retry (docs/protocol.md section 3).
        self.seq = self._seqs[address] = (self._seqs.get(address, secrets.randbelow(256)) + 1) & 0xFF
        frame = encode(Packet(address, 0, self.seq, int(command), payload))
        timeout = self.timeout_s(len(frame), response_bytes, driver_s)
        started = time.perf_counter()
        self.stats.requests += 1
        self.stats.by_command[command.name] = self.stats.by_command.get(command.name, 0) + 1
        try:
            for attempt in range(self.retries + 1):
                if self.deadline is not None and time.perf_counter() >= self.deadline:
                    raise DeadlineError(f"driver {_addr(address)} passed its deadline during {command.name}")
                if attempt:
                    self.stats.retries += 1
                try:
                    self.port.write(frame)
                    self.stats.bytes_sent += len(frame)
                    reply = self._await(address, command, timeout)
                except OSError as exc:  # pyserial's SerialException is an OSError
                    raise PortLost(f"the serial port failed during {command.name} ({exc})") from None
                if reply is None:
                    continue
                if reply.is_error:
                    status, detail, message = parse_error(reply.payload)
                    name = Status(status).name if status in Status._value2member_map_ else str(status)
                    raise LinkError(f"driver {_addr(address)} refused {command.name}: {name} "
                                    f"({message or 'no detail'})", status, detail)
                return reply
        finally:
            self.stats.busy_s += time.perf_counter() - started
        raise LinkError(f"driver {_addr(address)} did not answer {command.name} "
                        f"({self.retries + 1} attempts, {timeout * 1e3:.0f} ms each); check the cable, the "
                        "driver's power and its bus address")

    def _await(self, address: int, command: Command, timeout: float) -> Packet | None:
        deadline = time.perf_counter() + timeout
        if self.deadline is not None:
            deadline = min(deadline, self.deadline)
        while True:
            left = deadline - time.perf_counter()
            if left <= 0:
                return None
            self.port.timeout = left
            data = self.port.read(max(1, self.port.in_waiting))
            if not data:
                continue
            self.stats.bytes_received += len(data)
            packets, dropped = self._deframer.packets(data)
            self.stats.dropped_frames += dropped
            for p in packets:
                if (p.flags & FLAG_RESPONSE and p.seq == self.seq and p.command == command
                        and (p.address == address or address == 0xFFFF)):
                    return p


def _addr(address: int) -> str:
    return "(any)" if address == 0xFFFF else f"at address {address}"
