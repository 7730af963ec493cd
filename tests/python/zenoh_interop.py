"""Interop with an independent zenoh peer (the `eclipse-zenoh` package) that speaks to
ist_monitor the way rmw_zenoh does: key expressions `<domain>/<topic>/<DDS type>/<type hash>`,
CDR payloads with their encapsulation header, and the rmw_zenoh attachment (sequence number,
source timestamp, source gid).

    zenoh_interop.py ENDPOINT TOPIC=FILE,TYPE ...

Connects to ENDPOINT (a router, tcp/localhost:7447), then, for each TOPIC=FILE in order,
publishes the CDR payload in FILE on TOPIC at 10 Hz for 2 s with its header stamp set to now
(bytes 4..12 of the payload: sec, nanosec), while listening on
`0/ist_monitor/min_distance/**`. TYPE is the DDS type name (`sensor_msgs::msg::dds_::Image_`).
Prints, as JSON, {topic: [distances received while it was published]}.

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


def main():
    refuse_outside_private_network()
    import zenoh

    endpoint = sys.argv[1]
    plan = []
    for arg in sys.argv[2:]:
        topic, rest = arg.split("=", 1)
        path, dds_type = rest.split(",", 1)
        with open(path, "rb") as f:
            plan.append((topic, dds_type, bytearray(f.read())))
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(conf)
    received = []
    lock = threading.Lock()

    def on_distance(sample):
        payload = bytes(sample.payload.to_bytes())
        # CDR: 4-byte encapsulation header, then the float64 (little endian for 00 01).
        little = payload[1] == 1
        (value,) = struct.unpack("<d" if little else ">d", payload[4:12])
        with lock:
            received.append((time.monotonic(), value))

    sub = session.declare_subscriber("0/ist_monitor/min_distance/**", on_distance)
    time.sleep(1.0)
    gid = os.urandom(16)
    out = {}
    for topic, dds_type, payload in plan:
        # A concrete key as a publisher must use; subscribers take any hash.
        key = f"0/{topic.strip('/')}/{dds_type}/RIHS01_" + "0" * 64
        pub = session.declare_publisher(key)
        time.sleep(0.5)
        start = time.monotonic()
        for seq in range(1, 21):
            now = time.time_ns()
            struct.pack_into("<iI", payload, 4, now // 10**9, now % 10**9)
            attachment = struct.pack("<qq16s", seq, now, gid)
            pub.put(bytes(payload), attachment=attachment)
            time.sleep(0.1)
        time.sleep(0.5)
        with lock:
            out[topic] = [v for (t, v) in received if t >= start]
            received.clear()
        pub.undeclare()
    sub.undeclare()
    session.close()
    print(json.dumps(out))


if __name__ == "__main__":
    main()
