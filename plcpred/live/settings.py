"""What ``watch`` and ``serve`` need to know of the OPC UA side: the machine file's
``[live]`` table completed with defaults, and the node id of every signal."""
from __future__ import annotations

import re
from dataclasses import dataclass, field, fields

from ..errors import PlcpredError

DEFAULT_TEMPLATE = "ns=2;s={signal}"
# the names serve gives its flow meter and supply pressure (node ids by the template)
METER_NAME = "flow_l_min"
PRESSURE_NAME = "supply_bar_g"
DEFAULT_TAU_S = 0.2
PASSWORD_ENV = "PLCPRED_OPCUA_PASSWORD"

_ENDPOINT = re.compile(r"opc\.tcp://(\[[0-9a-fA-F:.]+\]|[A-Za-z0-9_.-]+):(\d{1,5})(/\S*)?")


class LiveError(PlcpredError):
    """A bad endpoint, node or option of ``watch`` or ``serve`` (exit 2)."""


@dataclass
class LiveSettings:
    """``[live]`` with its defaults (docs/reference/machine-file.md). The password is
    never held here: it is read from ``password_env`` when the client connects."""
    endpoint: str | None = None
    node_template: str = DEFAULT_TEMPLATE
    nodes: dict = field(default_factory=dict)
    meter_node: str | None = None
    meter_unit: str = "l/min"
    meter_reference: str = "iso8778"
    meter_tau_s: float = DEFAULT_TAU_S
    pressure_node: str | None = None
    cycle_signal: str | None = None
    window_s: float = 60.0
    sampling_ms: float = 0.0
    publishing_ms: float = 100.0
    rotate_s: float = 3600.0
    gap_alarm_percent: float = 10.0
    gap_alarm_cycles: int = 3
    learn_cycles: int = 10       # the reference learned from this many first cycles (0: D1)
    diagnose_every_s: float | None = None   # machine time between diagnoses (None: none)
    prometheus: str | None = None           # [HOST:]PORT of the metrics (None: none)
    plot: bool = False                      # comparison.png drawn when the watch ends
    idle_limit_l_min: float | None = None
    security_policy: str = "None"
    security_mode: str = "SignAndEncrypt"
    certificate: str | None = None
    private_key: str | None = None
    user: str | None = None
    password_env: str = PASSWORD_ENV

    def node_id(self, signal: str) -> str:
        """The node id of a machine-file signal: ``nodes``' entry, else the template's."""
        return self.nodes.get(signal) or self.node_template.replace("{signal}", signal)

    def meter_node_id(self) -> str:
        return self.meter_node or self.node_id(METER_NAME)

    def pressure_node_id(self) -> str:
        return self.pressure_node or self.node_id(PRESSURE_NAME)

    def shown(self) -> dict:
        """What may be logged: everything but where the secrets are."""
        return {f.name: getattr(self, f.name) for f in fields(self)
                if f.name not in ("certificate", "private_key", "password_env")}


def check_endpoint(url: str) -> tuple[str, int]:
    """(host, port) of an ``opc.tcp://host:port[/path]`` endpoint, or a LiveError."""
    m = _ENDPOINT.fullmatch(url.strip()) if isinstance(url, str) else None
    if m is None or not 0 < int(m.group(2)) < 65536:
        raise LiveError(f"endpoint {str(url)[:200]!r}: expected opc.tcp://HOST:PORT, as in "
                        "opc.tcp://127.0.0.1:4840")
    return m.group(1).strip("[]"), int(m.group(2))


def live_settings(machine, endpoint: str | None = None, **overrides) -> LiveSettings:
    """The machine's ``[live]`` (as the loader checked it) with defaults, the meter's
    reference and response time from ``[meter]`` where ``[live]`` leaves them out, the
    cycle signal from ``[machine]``; ``endpoint`` and ``overrides`` (not None) win."""
    given = dict(getattr(machine, "live", None) or {})
    meter = machine.meter
    s = LiveSettings(cycle_signal=machine.cycle_signal)
    if meter is not None:
        s.meter_reference = meter.reference
        if meter.tau_s is not None:
            s.meter_tau_s = meter.tau_s
    for key, value in {**given, **{k: v for k, v in overrides.items() if v is not None}}.items():
        setattr(s, key, value)
    s.gap_alarm_cycles = int(s.gap_alarm_cycles)
    s.learn_cycles = int(s.learn_cycles)
    if endpoint is not None:
        s.endpoint = endpoint
    if s.endpoint is None:
        raise LiveError(f"{machine.path}: no endpoint: give --endpoint opc.tcp://HOST:PORT or "
                        "[live] endpoint in the machine file")
    check_endpoint(s.endpoint)
    return s


def machine_signals(machine) -> list[str]:
    """Every signal the machine file names, once, in its order: the valves, the end
    switches, the inputs the world drives and the cycle signal."""
    names: list[str] = []
    for c in machine.consumers:
        names += list(c.valve)
    for c in machine.consumers:
        names += list(c.switches.values())
    names += [s.signal for s in machine.inputs]
    if machine.cycle_signal:
        names.append(machine.cycle_signal)
    return list(dict.fromkeys(names))
