"""Members and intruders of a secured zenoh cell (docs/security.md), each a zenoh session of
its own (the `eclipse-zenoh` package) in this one process, speaking to ist_monitor as rmw_zenoh
does (keys, hashes and attachments of zenoh_interop.py).

    zenoh_secure_peer.py PLAN.json

PLAN: {"topic": the cloud topic, "seconds": how long every session publishes,
       "wait": how long to wait for the first session's first distance,
       "settle": how long the others' sessions are given to be known before recording (2 s),
       "sessions": [{"name", "config": {zenoh config key: JSON5 value as a string},
                     "cloud": path of a CDR PointCloud2}, ...]}.

The first session is the camera: it opens, subscribes to `/ist_monitor/min_distance` and
publishes its cloud at 10 Hz until the node answers (at most `wait` s). Then every other session
tries to open with its own config (a failure is recorded, not fatal), subscribes to
`/ist_monitor/min_distance` where it can, and for `seconds` s each session that opened publishes
its cloud at 10 Hz, 50 ms after the camera's (the header stamp set to now, each with its own gid).
Each session that opens declares its publisher's liveliness token as rmw_zenoh does (kind `MP`,
node named after the session), so that the node's discovery sees it where the router lets it.
Prints, as JSON, {name: {"opened": bool, "error": the reason it did not open, or null,
"distances": [the distances this session received while they all published]}}.

Run it only inside ../shared/tools/netns-run (only loopback); it refuses to start elsewhere.
"""
import json
import os
import struct
import sys
import threading
import time

from zenoh_interop import ROS_2_HASH, key, refuse_outside_private_network

CLOUD_TYPE = "sensor_msgs::msg::dds_::PointCloud2_"
DISTANCE = ("/ist_monitor/min_distance", "std_msgs::msg::dds_::Float64_")


class Member:
    """One session: its config, its cloud, what it received."""

    def __init__(self, zenoh, spec, topic):
        self.name = spec["name"]
        with open(spec["cloud"], "rb") as f:
            self.cloud = bytearray(f.read())
        self.gid = os.urandom(16)
        self.seq = 0
        self.distances = []
        self.recording = False
        self.lock = threading.Lock()
        self.error = None
        self.session = None
        self.pub = None
        conf = zenoh.Config()
        for k, v in spec["config"].items():
            conf.insert_json5(k, v)
        try:
            self.session = zenoh.open(conf)
        except Exception as e:  # zenoh.ZError: the router refused it, or no link opened
            self.error = str(e) or type(e).__name__
            return
        self.sub = self.session.declare_subscriber(key(*DISTANCE), self.on_distance)
        self.pub = self.session.declare_publisher(key(topic, CLOUD_TYPE))
        # rmw_zenoh's token of a publisher: node 0, entity 1, enclave and namespace empty,
        # best-effort KeepLast 5 (sensor data).
        mangled = "/" + topic.strip("/")
        self.token = self.session.liveliness().declare_token(
            f"@ros2_lv/0/{self.session.zid()}/0/1/MP/%/%/{self.name}/"
            f"{mangled.replace('/', '%')}/{CLOUD_TYPE}/{ROS_2_HASH[CLOUD_TYPE]}/2::,5:,:,:,,")

    def on_distance(self, sample):
        payload = bytes(sample.payload.to_bytes())
        (value,) = struct.unpack("<d" if payload[1] == 1 else ">d", payload[4:12])
        with self.lock:
            if self.recording:
                self.distances.append(value)
            else:
                self.distances[:] = [value]

    def publish(self):
        if self.pub is None:
            return
        self.seq += 1
        now = time.time_ns()
        struct.pack_into("<iI", self.cloud, 4, now // 10**9, now % 10**9)
        self.pub.put(bytes(self.cloud), attachment=struct.pack("<qq16s", self.seq, now, self.gid))

    def report(self):
        with self.lock:
            return {
                "opened": self.session is not None,
                "error": self.error,
                "distances": list(self.distances),
            }


def main():
    refuse_outside_private_network()
    import zenoh

    with open(sys.argv[1]) as f:
        plan = json.load(f)
    topic = plan["topic"]
    camera = Member(zenoh, plan["sessions"][0], topic)
    if camera.session is None:
        sys.exit(f"zenoh_secure_peer.py: the camera's session did not open: {camera.error}")
    deadline = time.monotonic() + plan["wait"]
    while time.monotonic() < deadline:
        camera.publish()
        time.sleep(0.1)
        with camera.lock:
            if camera.distances:
                break
    others = [Member(zenoh, spec, topic) for spec in plan["sessions"][1:]]
    # The others' publishers, tokens and subscribers reach the router and, through it, the node
    # (0.5 s was once too little on a loaded CI machine: the node answered the camera before it
    # knew the second writer).
    time.sleep(plan.get("settle", 2.0))
    members = [camera] + others
    for m in members:
        with m.lock:
            m.distances.clear()
            m.recording = True
    end = time.monotonic() + plan["seconds"]
    while time.monotonic() < end:
        camera.publish()
        time.sleep(0.05)
        for m in others:
            m.publish()
        time.sleep(0.05)
    time.sleep(0.5)
    out = {m.name: m.report() for m in members}
    for m in members:
        if m.session is not None:
            m.session.close()
    print(json.dumps(out))


if __name__ == "__main__":
    main()
