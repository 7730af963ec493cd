"""Interop with an independent zenoh peer (the `eclipse-zenoh` package) that speaks to
ist_monitor the way rmw_zenoh does: key expressions `<domain>/<topic>/<DDS type>/<type hash>`
with each type's REP-2016 hash as ROS 2 Jazzy computes it (the table below, copied from the
code ROS 2 generates, not from ist_monitor), CDR payloads with their encapsulation header, and
the rmw_zenoh attachment (sequence number, source timestamp, source gid).

    zenoh_interop.py ENDPOINT [--latched TOPIC=FILE,TYPE] [--delay S] [--together]
                     [--set NAME=DOUBLE] TOPIC=FILE,TYPE ...

Connects to ENDPOINT (a router, tcp/localhost:7447). `--latched` publishes that message once, at
once, as rmw_zenoh publishes a transient-local topic (`/tf_static`): from a cache that
late-joining subscribers query. After `--delay` seconds (default 0), for each TOPIC=FILE in order,
publishes the CDR payload in FILE on TOPIC at 10 Hz for 2 s with its header stamp set to now
(with `--together`, every TOPIC in each 10 Hz cycle, in order, for 2 s: the distances are then
listed under "together")
(bytes 4..12 of the payload: sec, nanosec), while subscribed, as an rmw_zenoh subscriber is, to
the exact keys of `/ist_monitor/min_distance` (Float64) and `/diagnostics` (DiagnosticArray).
TYPE is the DDS type name (`sensor_msgs::msg::dds_::Image_`). Prints, as JSON:
{"distances": {topic: [distances received while it was published]}, "diagnostics": count,
"attachments": [[length, sequence number], ...] of the distances, "lower_m": {status name:
the last `lower_m` value of that status in /diagnostics}, "liveliness": [the keys of
the liveliness tokens under @ros2_lv/0/**], "speed_scaling": [the factors in the node's
`~/speed_scaling` cache that a late-joining rmw_zenoh subscriber receives], "parameters": [the
names `/ist_monitor/list_parameters` answers, asked as an rmw_zenoh client asks],
"parameters_reply_sequence": the sequence number of that reply's attachment, "set": [successful,
reason] of `/ist_monitor/set_parameters` setting NAME to DOUBLE (`--set`; null without it),
"parameter_events": [each `/parameter_events` message heard since the start, as {"node", "stamp_ns",
"new", "changed", "deleted"}, each parameter [name, type, double value]]}.

Zenoh may scout by multicast: run it only inside ../shared/tools/netns-run (only loopback). It
refuses to start anywhere else.
"""
import json
import os
import struct
import sys
import threading
import time


def refuse_outside_private_network():
    with open("/proc/self/net/dev") as f:
        interfaces = sorted(line.split(":")[0].strip() for line in f.readlines()[2:])
    if interfaces != ["lo"]:
        sys.exit(f"zenoh_interop.py: interfaces {interfaces}: run it inside netns-run")


# RIHS01 hashes of ROS 2 Jazzy (rosidl_generator_c's `<type>__description.c`).
ROS_2_HASH = {
    "std_msgs::msg::dds_::Float64_":
        "RIHS01_705ba9c3d1a09df43737eb67095534de36fd426c0587779bda2bc51fe790182a",
    "diagnostic_msgs::msg::dds_::DiagnosticArray_":
        "RIHS01_5a8a36efb05fb25070fa0fb3810290c0e6cd4862b54a8fb975a1ee8dc55a333e",
    "sensor_msgs::msg::dds_::PointCloud2_":
        "RIHS01_9198cabf7da3796ae6fe19c4cb3bdd3525492988c70522628af5daa124bae2b5",
    "sensor_msgs::msg::dds_::Image_":
        "RIHS01_d31d41a9a4c4bc8eae9be757b0beed306564f7526c88ea6a4588fb9582527d47",
    "sensor_msgs::msg::dds_::CameraInfo_":
        "RIHS01_b3dfd68ff46c9d56c80fd3bd4ed22c7a4ddce8c8348f2f59c299e73118e7e275",
    "tf2_msgs::msg::dds_::TFMessage_":
        "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
    "control_msgs::msg::dds_::SpeedScalingFactor_":
        "RIHS01_0c240f349f2b74e33e8741f83e0f196ddeb6585923663876ed3c1f51f0566037",
    "rcl_interfaces::msg::dds_::ParameterEvent_":
        "RIHS01_043e627780fcad87a22d225bc2a037361dba713fca6a6b9f4b869a5aa0393204",
    "rcl_interfaces::srv::dds_::ListParameters_":
        "RIHS01_3e6062bfbb27bfb8730d4cef2558221f51a11646d78e7bb30a1e83afac3aad9d",
    "rcl_interfaces::srv::dds_::SetParameters_":
        "RIHS01_56eed9a67e169f9cb6c1f987bc88f868c14a8fc9f743a263bc734c154015d7e0",
}


def key(topic, dds_type):
    return f"0/{topic.strip('/')}/{dds_type}/{ROS_2_HASH[dds_type]}"


class Cdr:
    """A reader of a CDR payload (encapsulation header, then either byte order)."""

    def __init__(self, payload):
        self.little = payload[1] == 1
        self.b = payload[4:]
        self.pos = 0

    def take(self, fmt, size):
        self.pos += (-self.pos) % size
        (v,) = struct.unpack_from(("<" if self.little else ">") + fmt, self.b, self.pos)
        self.pos += size
        return v

    def u8(self):
        return self.take("B", 1)

    def u32(self):
        return self.take("I", 4)

    def f64(self):
        return self.take("d", 8)

    def string(self):
        n = self.u32()
        s = self.b[self.pos:self.pos + n - 1].decode()
        self.pos += n
        return s

    def parameter_value(self):
        """rcl_interfaces/ParameterValue as [type, double_value] (the arrays skipped)."""
        kind = self.u8()
        self.u8()  # bool_value
        self.take("q", 8)  # integer_value
        value = self.f64()
        self.string()
        for size in (1, 1, 8, 8):  # byte, bool, int64 and float64 arrays
            n = self.u32()
            self.pos += (-self.pos) % size if n else 0
            self.pos += n * size
        for _ in range(self.u32()):
            self.string()
        return [kind, value]


class CdrWriter:
    """A little-endian CDR payload, with its encapsulation header."""

    def __init__(self):
        self.b = bytearray()

    def put(self, fmt, size, v):
        self.b += bytes((-len(self.b)) % size)
        self.b += struct.pack("<" + fmt, v)

    def string(self, s):
        data = s.encode() + b"\0"
        self.put("I", 4, len(data))
        self.b += data

    def payload(self):
        return bytes([0, 1, 0, 0]) + bytes(self.b)


def parse_diagnostics(payload):
    """The (name, {key: value}) of each status of a CDR diagnostic_msgs/DiagnosticArray."""
    c = Cdr(payload)
    c.u32(), c.u32(), c.string()  # header: stamp, frame_id
    statuses = []
    for _ in range(c.u32()):
        c.u8()  # level
        name, _message, _hardware_id = c.string(), c.string(), c.string()
        values = {}
        for _ in range(c.u32()):
            k = c.string()
            values[k] = c.string()
        statuses.append((name, values))
    return statuses


def parse_strings(payload):
    """The first string sequence of a CDR payload (ListParameters_Response: result.names)."""
    c = Cdr(payload)
    return [c.string() for _ in range(c.u32())]


def parse_parameter_event(payload):
    """A CDR rcl_interfaces/ParameterEvent as {"node", "stamp_ns", "new", "changed", "deleted"}."""
    c = Cdr(payload)
    sec = c.take("i", 4)
    stamp_ns = sec * 10**9 + c.u32()
    event = {"node": c.string(), "stamp_ns": stamp_ns}
    for part in ("new", "changed", "deleted"):
        event[part] = [[c.string()] + c.parameter_value() for _ in range(c.u32())]
    return event


def set_double_request(name, value):
    """A CDR SetParameters_Request setting `name` to the double `value`."""
    w = CdrWriter()
    w.put("I", 4, 1)  # one parameter
    w.string(name)
    w.put("B", 1, 3)  # PARAMETER_DOUBLE
    w.put("B", 1, 0)  # bool_value
    w.put("q", 8, 0)  # integer_value
    w.put("d", 8, value)
    w.string("")
    for _ in range(5):  # the five arrays, empty
        w.put("I", 4, 0)
    return w.payload()


def call(session, gid, service, dds_type, request, sequence):
    """A request to the node's `service` as an rmw_zenoh client makes it: the payload and
    the client's attachment (the reply's carries `sequence` back). The reply's (payload,
    sequence number), or (None, None)."""
    key = f"0/ist_monitor/{service}/{dds_type}/{ROS_2_HASH[dds_type]}"
    attachment = struct.pack("<qq", sequence, time.time_ns()) + gid
    for reply in session.get(key, payload=request, attachment=attachment, timeout=10.0):
        if reply.ok is not None:
            a = reply.ok.attachment
            seq = struct.unpack("<q", bytes(a.to_bytes())[:8])[0] if a is not None else None
            return bytes(reply.ok.payload.to_bytes()), seq
    return None, None


def main():
    refuse_outside_private_network()
    import zenoh
    import zenoh.ext

    endpoint = sys.argv[1]
    plan = []
    latched = []
    delay = 0.0
    together = False
    to_set = None
    args = iter(sys.argv[2:])
    for arg in args:
        if arg == "--set":
            name, value = next(args).split("=", 1)
            to_set = (name, float(value))
            continue
        if arg == "--together":
            together = True
            continue
        if arg == "--delay":
            delay = float(next(args))
            continue
        target = latched if arg == "--latched" else plan
        if arg == "--latched":
            arg = next(args)
        topic, rest = arg.split("=", 1)
        path, dds_type = rest.split(",", 1)
        with open(path, "rb") as f:
            target.append((topic, dds_type, bytearray(f.read())))
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    # As rmw_zenoh's default session config: a transient-local cache orders by timestamp.
    conf.insert_json5("timestamping/enabled", "true")
    session = zenoh.open(conf)
    gid = os.urandom(16)
    keep = []
    for topic, dds_type, payload in latched:
        pub = zenoh.ext.declare_advanced_publisher(
            session,
            key(topic, dds_type),
            cache=zenoh.ext.CacheConfig(max_samples=1),
            publisher_detection=True,
        )
        pub.put(bytes(payload), attachment=struct.pack("<qq16s", 1, time.time_ns(), gid))
        keep.append(pub)
    time.sleep(delay)
    received = []
    attachments = []
    diagnostics = [0]
    lock = threading.Lock()

    def on_distance(sample):
        payload = bytes(sample.payload.to_bytes())
        # CDR: 4-byte encapsulation header, then the float64 (little endian for 00 01).
        little = payload[1] == 1
        (value,) = struct.unpack("<d" if little else ">d", payload[4:12])
        a = sample.attachment
        a = bytes(a.to_bytes()) if a is not None else b""
        seq = struct.unpack("<q", a[:8])[0] if len(a) >= 8 else None
        with lock:
            received.append((time.monotonic(), value))
            attachments.append([len(a), seq])

    lower_m = {}

    def on_diagnostics(sample):
        statuses = parse_diagnostics(bytes(sample.payload.to_bytes()))
        with lock:
            diagnostics[0] += 1
            for name, values in statuses:
                if "lower_m" in values:
                    lower_m[name] = float(values["lower_m"])

    events = []

    def on_event(sample):
        event = parse_parameter_event(bytes(sample.payload.to_bytes()))
        with lock:
            events.append(event)

    event_sub = session.declare_subscriber(
        key("/parameter_events", "rcl_interfaces::msg::dds_::ParameterEvent_"), on_event
    )
    sub = session.declare_subscriber(
        key("/ist_monitor/min_distance", "std_msgs::msg::dds_::Float64_"), on_distance
    )
    diag = session.declare_subscriber(
        key("/diagnostics", "diagnostic_msgs::msg::dds_::DiagnosticArray_"), on_diagnostics
    )
    time.sleep(1.0)
    liveliness = [
        str(reply.ok.key_expr)
        for reply in session.liveliness().get("@ros2_lv/0/**", timeout=2.0)
        if reply.ok is not None
    ]
    out = {}
    groups = [plan] if together else [[p] for p in plan]
    for group in groups:
        pubs = [session.declare_publisher(key(topic, dds_type)) for topic, dds_type, _ in group]
        time.sleep(0.5)
        start = time.monotonic()
        for seq in range(1, 21):
            for pub, (_, _, payload) in zip(pubs, group):
                now = time.time_ns()
                struct.pack_into("<iI", payload, 4, now // 10**9, now % 10**9)
                attachment = struct.pack("<qq16s", seq, now, gid)
                pub.put(bytes(payload), attachment=attachment)
            time.sleep(0.1)
        time.sleep(0.5)
        with lock:
            out["together" if together else group[0][0]] = [
                v for (t, v) in received if t >= start
            ]
            received.clear()
        for pub in pubs:
            pub.undeclare()
    # What a late joiner gets: a transient-local subscription as rmw_zenoh makes one (an
    # advanced subscriber that fetches the history of the publishers it detects) receives the
    # node's last speed-scaling factors from its publisher's cache: the samples stamped (source
    # timestamp, in the attachment) before the subscription was made.
    scaling = key("/ist_monitor/speed_scaling", "control_msgs::msg::dds_::SpeedScalingFactor_")
    speed_scaling = []
    joined = time.time_ns()

    def on_scaling(sample):
        p = bytes(sample.payload.to_bytes())
        a = bytes(sample.attachment.to_bytes()) if sample.attachment is not None else b""
        if len(a) >= 16 and struct.unpack("<q", a[8:16])[0] < joined:
            with lock:
                speed_scaling.append(struct.unpack("<d" if p[1] == 1 else ">d", p[4:12])[0])

    late = zenoh.ext.declare_advanced_subscriber(
        session,
        scaling,
        on_scaling,
        history=zenoh.ext.HistoryConfig(detect_late_publishers=True, max_samples=1),
    )
    time.sleep(1.0)
    # `ros2 param list` over rmw_zenoh: a ListParameters_Request (no prefixes; depth 0: all).
    request = CdrWriter()
    request.put("I", 4, 0)
    request.put("Q", 8, 0)
    reply, reply_sequence = call(session, gid, "list_parameters",
                                 "rcl_interfaces::srv::dds_::ListParameters_",
                                 request.payload(), 41)
    parameters = parse_strings(reply) if reply is not None else None
    # `ros2 param set` over rmw_zenoh: SetParameters_Response is results[] of (successful,
    # reason); the change is then announced on /parameter_events.
    set_result = None
    if to_set is not None:
        reply, _ = call(session, gid, "set_parameters",
                        "rcl_interfaces::srv::dds_::SetParameters_",
                        set_double_request(*to_set), 42)
        if reply is not None:
            c = Cdr(reply)
            set_result = [[c.u8() == 1, c.string()] for _ in range(c.u32())]
        time.sleep(1.0)
    late.undeclare()
    event_sub.undeclare()
    sub.undeclare()
    diag.undeclare()
    session.close()
    print(
        json.dumps(
            {
                "distances": out,
                "diagnostics": diagnostics[0],
                "attachments": attachments,
                "liveliness": liveliness,
                "speed_scaling": speed_scaling,
                "lower_m": lower_m,
                "parameters": parameters,
                "parameters_reply_sequence": reply_sequence,
                "set": set_result,
                "parameter_events": events,
            }
        )
    )


if __name__ == "__main__":
    main()
