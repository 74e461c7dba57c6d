"""``watch --prometheus [HOST:]PORT``: the live comparison as Prometheus metrics, for
the dashboards a plant already runs.

``prometheus-client`` is imported only when metrics are asked for (it is no dependency
of plcpred); its HTTP server answers scrapes from a thread of its own, so a scrape never
holds recording up."""
from __future__ import annotations

from .settings import LiveError

PREFIX = "plcpred_watch_"


def parse_address(text: str) -> tuple[str, int]:
    """(host, port) of ``PORT`` (every interface) or ``HOST:PORT``."""
    host, _, port = str(text).strip().rpartition(":")
    try:
        number = int(port)
    except ValueError:
        number = -1
    if not 0 < number < 65536:
        raise LiveError(f"--prometheus {text!r}: expected a port (9109) or HOST:PORT "
                        "(127.0.0.1:9109)")
    return host.strip("[]") or "0.0.0.0", number


class Metrics:
    """The gauges and counters of one watch, served at ``address``."""

    def __init__(self, address: str, machine_name: str):
        # an optional package: imported only by a watch given --prometheus
        try:
            import prometheus_client as pc
        except ImportError:
            raise LiveError("--prometheus needs the prometheus-client package: pip install "
                            "prometheus-client") from None
        host, port = parse_address(address)
        self.registry = pc.CollectorRegistry()
        labels = {"machine": machine_name}

        def gauge(name, text, extra=()):
            g = pc.Gauge(PREFIX + name, text, ["machine", *extra], registry=self.registry)
            return g if extra else g.labels(**labels)

        def counter(name, text):
            return pc.Counter(PREFIX + name, text, ["machine"],
                              registry=self.registry).labels(**labels)

        self.labels = labels
        self.cycles = counter("cycles", "cycles (or windows) compared")
        self.gaps = counter("gaps", "gaps in the recording (connection lost, no history)")
        self.measured = gauge("cycle_measured_nl", "the last cycle's measured air (NL)")
        self.reference = gauge("cycle_reference_nl",
                               "the last cycle's air by the learned reference (NL)")
        self.d1 = gauge("cycle_d1_nl", "the last cycle's air by the activation model (NL)")
        self.gap = gauge("gap_percent", "the last cycle's gap to the reference (%)")
        self.d1_gap = gauge("d1_gap_percent", "the last cycle's gap to D1 (%)")
        self.rolling = gauge("rolling_gap_percent", "the gap over the last ten cycles (%)")
        self.idle = gauge("idle_flow_l_min", "the flow while the machine rests (NL/min)")
        self.learned = gauge("reference_learned", "1 once the reference is learned")
        self.connected = gauge("connected", "1 while connected to the OPC UA server")
        self.alarm = gauge("alarm", "1 while the alarm is raised", ["alarm"])
        self.verdict = pc.Info(PREFIX + "diagnosis", "the last periodic diagnosis",
                               ["machine"], registry=self.registry).labels(**labels)
        try:
            self.server, self.thread = pc.start_http_server(port, addr=host,
                                                            registry=self.registry)
        except OSError as e:
            raise LiveError(f"--prometheus: cannot serve metrics at {host}:{port}: "
                            f"{e.strerror or e}") from None

    def cycle(self, r) -> None:
        self.cycles.inc()
        self.measured.set(r.measured_nl)
        self.d1.set(r.predicted_nl)
        for gauge, value in ((self.reference, r.reference_nl),
                             (self.gap, _pct(r.reference_gap)), (self.d1_gap, _pct(r.gap)),
                             (self.rolling, _pct(r.rolling_gap)), (self.idle, r.idle_l_min)):
            if value is not None:
                gauge.set(value)
        self.learned.set(0 if r.reference.startswith("learning") else 1)

    def alarm_state(self, kind: str, raised: bool) -> None:
        self.alarm.labels(**self.labels, alarm=kind).set(1 if raised else 0)

    def diagnosis(self, fields: dict) -> None:
        self.verdict.info({"verdict": str(fields.get("verdict", "failed")),
                           "window_to": str(fields.get("window_to", "")),
                           "onset": str(fields.get("onset", ""))})

    def close(self) -> None:
        self.server.shutdown()
        self.server.server_close()


def _pct(x):
    return None if x is None else 100.0 * x
