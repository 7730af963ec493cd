"""An independent ROS 2 camera over DDS (Eclipse Cyclone DDS, the `cyclonedds` package) that
publishes a real organized cloud, as a PointCloud2 or as the 16UC1 depth image and CameraInfo
made from it, at a given rate with fresh stamps, and measures the node's answers on
~/link_distances (stamped with the cloud's stamp): how many came back and how late.

    camera_peer.py BAG --mode cloud|depth [--transport dds|zenoh|rclpy] [--rate HZ]
                   [--duration S] [--node /ist_monitor] [--topic T] [--connect tcp/localhost:7447]
                   [--node-pid PID]

BAG is a rosbag2 holding an organized PointCloud2 (the first is used; the real Kinect bag of
../shared/bags/moveit_perception_tutorial). `cloud` publishes it as it is (its own point_step)
on its topic; `depth` publishes the depth image a driver would have sent: each point's z in
millimetres (0 where the point is NaN), with the pinhole K fitted to the cloud's points by least
squares (u = fx·x/z + cx, v = fy·y/z + cy; the residual is printed), on
<topic namespace>/image_raw and <topic namespace>/camera_info (QoS sensor data: best effort,
keep last 1). Prints one JSON line: published, answered, latency p50/p99/max (ms), the
publisher's own share of it (from the stamp until write/put returned) and the rest (from then
to the answer: middleware and node), p50/p99, the sizes.

`--transport rclpy` publishes them with ROS 2 Jazzy's own client, rclpy on rmw_fastrtps_cpp (Fast
DDS; the venv's ros-jazzy packages): each message serialized once by rclpy, its stamp patched in
the bytes and the bytes published, as a C++ driver hands over a ready message; the answers are
read by an rclpy subscription. `--node-pid` adds the node's CPU use over the publishing (% of one
core, from /proc) and its peak resident memory to the line.

`--transport zenoh` publishes the same messages the way rmw_zenoh does (key
`<domain>/<topic>/<DDS type>/<type hash>`, CDR payload with its encapsulation header, the rmw_zenoh
attachment), connected to the router at `--connect`; or with the session config of
`--zenoh-config FILE` (e.g. config/zenoh/secure_session.json5: TLS with a certificate, relative
paths from the working directory) and `--zenoh-override 'key=value;...'` on top (as
ZENOH_CONFIG_OVERRIDE, e.g. the camera's own certificate and key).

DDS discovers by multicast: run it only inside ../shared/tools/netns-run, where loopback is the
only interface. It refuses to start anywhere else.
"""
import argparse
import json
import os
import struct
import sys
import threading
import time
from dataclasses import dataclass

import numpy as np


def refuse_outside_private_network():
    # /proc/self/net/dev lists the interfaces of this process's network namespace (sysfs may
    # still show the host's).
    with open("/proc/self/net/dev") as f:
        interfaces = sorted(line.split(":")[0].strip() for line in f.readlines()[2:])
    if interfaces != ["lo"]:
        sys.exit(
            f"camera_peer.py: network interfaces {interfaces}: run it inside "
            "../shared/tools/netns-run (only loopback), DDS discovery must not leave this machine"
        )


def read_cloud(bag):
    from rosbags.highlevel import AnyReader
    from pathlib import Path

    with AnyReader([Path(bag)]) as reader:
        for con, _, raw in reader.messages():
            if con.msgtype == "sensor_msgs/msg/PointCloud2":
                return con.topic, reader.deserialize(raw, con.msgtype)
    sys.exit(f"{bag}: no sensor_msgs/msg/PointCloud2")


def xyz(cloud):
    offsets = {f.name: f.offset for f in cloud.fields}
    n = cloud.width * cloud.height
    data = np.frombuffer(bytes(cloud.data), dtype=np.uint8).reshape(n, cloud.point_step)
    out = np.empty((n, 3), dtype=np.float32)
    for i, name in enumerate("xyz"):
        o = offsets[name]
        out[:, i] = data[:, o:o + 4].copy().view("<f4")[:, 0]
    return out


def fit_intrinsics(points, width):
    """fx, fy, cx, cy of the pinhole camera whose rays the points lie on, and the rms pixel
    residual of the fit."""
    n = len(points)
    u = np.arange(n) % width
    v = np.arange(n) // width
    ok = np.isfinite(points).all(axis=1) & (points[:, 2] > 0)
    a = points[ok, 0] / points[ok, 2]
    b = points[ok, 1] / points[ok, 2]
    fx, cx = np.polyfit(a, u[ok], 1)
    fy, cy = np.polyfit(b, v[ok], 1)
    res = np.sqrt(np.mean((fx * a + cx - u[ok]) ** 2 + (fy * b + cy - v[ok]) ** 2))
    return float(fx), float(fy), float(cx), float(cy), float(res)


def depth_of(cloud, topic):
    """The depth image a driver would have sent for `cloud` (each point's z in millimetres, 0
    where it is NaN), the pinhole (fx, fy, cx, cy, rms px) fitted to its points, and the image
    and camera info topics beside the cloud's."""
    points = xyz(cloud)
    intrinsics = fit_intrinsics(points, cloud.width)
    z = points[:, 2]
    mm = np.where(np.isfinite(z) & (z > 0), np.round(z * 1000.0), 0).astype("<u2")
    ns = topic.rsplit("/", 1)[0]
    return mm.tobytes(), intrinsics, ns + "/image_raw", ns + "/camera_info"


def fast_byte_sequences():
    """cyclonedds writes a sequence<uint8> through struct.pack with one argument per byte (30 ms
    for a 614 KB image, 0.5 s for a 9.8 MB cloud): write bytes as one block instead, the same
    bytes on the wire."""
    from cyclonedds.idl import _machinery as machinery

    plain = machinery.PlainCdrV2SequenceOfPrimitiveMachine.serialize

    def serialize(self, buffer, value, *args, **kwargs):
        if self.code == "B" and isinstance(value, (bytes, bytearray)):
            buffer.align(4)
            buffer.write("I", 4, len(value))
            buffer.write_bytes(value)
            return
        plain(self, buffer, value, *args, **kwargs)

    machinery.PlainCdrV2SequenceOfPrimitiveMachine.serialize = serialize


def paced(args, publish, lock, sent, handed):
    """Calls `publish(stamp_ns)` at `args.rate` for `args.duration`, recording in `sent` when
    each stamp was taken and in `handed` when its publish returned (unless already answered).
    Returns the count and the publisher's own share of the latency per message, ms: from the
    stamp until the write/put returned (the message built, serialised and handed over)."""
    period, count = 1.0 / args.rate, int(args.duration * args.rate)
    start, publishing = time.monotonic(), []
    for i in range(count):
        delay = start + i * period - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        stamp_ns = time.time_ns()
        t0 = time.monotonic()
        with lock:
            sent[stamp_ns] = t0
        publish(stamp_ns)
        t1 = time.monotonic()
        with lock:
            if stamp_ns in sent:  # not answered yet
                handed[stamp_ns] = t1
        publishing.append((t1 - t0) * 1000.0)
    return count, publishing


def node_usage(pid):
    """(CPU seconds, peak resident MiB) of process `pid`."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    cpu = (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    with open(f"/proc/{pid}/status") as f:
        peak = next(int(line.split()[1]) for line in f if line.startswith("VmHWM:"))
    return cpu, peak / 1024.0


def run_rclpy(args):
    import rclpy
    from rclpy.qos import qos_profile_sensor_data, QoSProfile, ReliabilityPolicy
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import CameraInfo, Image, JointState, PointCloud2, PointField

    topic, cloud = read_cloud(args.bag)
    topic = args.topic or topic
    width, height = cloud.width, cloud.height
    rclpy.init()
    node = rclpy.create_node("camera_peer")
    info = {"mode": args.mode, "rate_hz": args.rate, "width": width, "height": height,
            "transport": "rclpy (rmw_fastrtps_cpp)"}

    def header_of(m):
        m.header.frame_id = cloud.header.frame_id
        return m

    if args.mode == "cloud":
        m = header_of(PointCloud2())
        m.height, m.width = height, width
        m.fields = [PointField(name=f.name, offset=f.offset, datatype=f.datatype, count=f.count)
                    for f in cloud.fields]
        m.is_bigendian, m.point_step, m.row_step = bool(cloud.is_bigendian), cloud.point_step, \
            cloud.row_step
        m.data, m.is_dense = bytes(cloud.data), bool(cloud.is_dense)
        pubs = [(node.create_publisher(PointCloud2, topic, qos_profile_sensor_data),
                 bytearray(serialize_message(m)))]
        info.update(topic=topic, bytes=len(cloud.data))
    else:
        payload, (fx, fy, cx, cy, res), image_topic, info_topic = depth_of(cloud, topic)
        ci = header_of(CameraInfo())
        ci.height, ci.width, ci.distortion_model = height, width, "plumb_bob"
        ci.d = [0.0] * 5
        ci.k = [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0]
        ci.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
        ci.p = [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0]
        im = header_of(Image())
        im.height, im.width, im.encoding, im.step = height, width, "16UC1", 2 * width
        im.data = payload
        pubs = [(node.create_publisher(CameraInfo, info_topic, qos_profile_sensor_data),
                 bytearray(serialize_message(ci))),
                (node.create_publisher(Image, image_topic, qos_profile_sensor_data),
                 bytearray(serialize_message(im)))]
        info.update(topic=image_topic, camera_info_topic=info_topic, bytes=len(im.data),
                    fx=fx, fy=fy, cx=cx, cy=cy, fit_rms_px=res)

    sent, latencies, lock = {}, [], threading.Lock()

    def on_answer(m):
        now = time.monotonic()
        stamp = m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
        with lock:
            at = sent.pop(stamp, None)
        if at is not None:
            latencies.append((now - at) * 1e3)

    node.create_subscription(JointState, args.node + "/link_distances", on_answer,
                             QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))
    from rclpy.executors import SingleThreadedExecutor
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    time.sleep(args.wait)
    usage0 = node_usage(args.node_pid) if args.node_pid else None
    def publish(stamp_ns):
        for pub, raw in pubs:
            # The header's stamp follows the 4-byte encapsulation: sec int32, nanosec uint32.
            struct.pack_into("<iI", raw, 4, stamp_ns // 10**9, stamp_ns % 10**9)
            pub.publish(bytes(raw))

    start = time.monotonic()
    count, publishing = paced(args, publish, lock, sent, {})
    elapsed = time.monotonic() - start
    time.sleep(1.0)
    if usage0:
        cpu1, peak = node_usage(args.node_pid)
        info.update(node_cpu_percent=round(100.0 * (cpu1 - usage0[0]) / elapsed, 1),
                    node_peak_mib=round(peak, 1))
    lat = sorted(latencies)
    q = lambda v, f: round(v[min(len(v) - 1, int(f * len(v)))], 2) if v else None
    pub = sorted(publishing)
    info.update(published=count, answered=len(lat), p50_ms=q(lat, 0.5), p99_ms=q(lat, 0.99),
                max_ms=round(lat[-1], 2) if lat else None, publish_p50_ms=q(pub, 0.5),
                publish_p99_ms=q(pub, 0.99))
    print(json.dumps(info), flush=True)
    executor.shutdown()
    spinner.join()
    node.destroy_node()
    rclpy.shutdown()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("bag")
    ap.add_argument("--mode", choices=["cloud", "depth"], required=True)
    ap.add_argument("--rate", type=float, default=30.0)
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--node", default="/ist_monitor")
    ap.add_argument("--topic", help="the topic to publish the cloud on (default: the bag's)")
    ap.add_argument("--wait", type=float, default=3.0, help="discovery time before publishing, s")
    ap.add_argument("--transport", choices=["dds", "zenoh", "rclpy"], default="dds")
    ap.add_argument("--node-pid", type=int, help="report this process's CPU and peak memory")
    ap.add_argument("--connect", default="tcp/localhost:7447")
    ap.add_argument("--zenoh-config", help="the zenoh session config file (else --connect)")
    ap.add_argument("--zenoh-override", default="", help="key=value;... on top of it")
    args = ap.parse_args()
    refuse_outside_private_network()
    if args.transport == "rclpy":
        return run_rclpy(args)
    fast_byte_sequences()

    from cyclonedds.core import Policy, Qos
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.idl import IdlStruct
    from cyclonedds.idl.types import array, float64, int32, sequence, uint8, uint32
    from cyclonedds.pub import DataWriter as CycloneWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic as CycloneTopic

    @dataclass
    class Time_(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
        sec: int32
        nanosec: uint32

    @dataclass
    class Header_(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
        stamp: Time_
        frame_id: str

    @dataclass
    class PointField_(IdlStruct, typename="sensor_msgs::msg::dds_::PointField_"):
        name: str
        offset: uint32
        datatype: uint8
        count: uint32

    @dataclass
    class PointCloud2_(IdlStruct, typename="sensor_msgs::msg::dds_::PointCloud2_"):
        header: Header_
        height: uint32
        width: uint32
        fields: sequence[PointField_]
        is_bigendian: bool
        point_step: uint32
        row_step: uint32
        data: sequence[uint8]
        is_dense: bool

    @dataclass
    class Image_(IdlStruct, typename="sensor_msgs::msg::dds_::Image_"):
        header: Header_
        height: uint32
        width: uint32
        encoding: str
        is_bigendian: uint8
        step: uint32
        data: sequence[uint8]

    @dataclass
    class RegionOfInterest_(IdlStruct, typename="sensor_msgs::msg::dds_::RegionOfInterest_"):
        x_offset: uint32
        y_offset: uint32
        height: uint32
        width: uint32
        do_rectify: bool

    @dataclass
    class CameraInfo_(IdlStruct, typename="sensor_msgs::msg::dds_::CameraInfo_"):
        header: Header_
        height: uint32
        width: uint32
        distortion_model: str
        d: sequence[float64]
        k: array[float64, 9]
        r: array[float64, 9]
        p: array[float64, 12]
        binning_x: uint32
        binning_y: uint32
        roi: RegionOfInterest_

    @dataclass
    class JointState_(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
        header: Header_
        name: sequence[str]
        position: sequence[float64]
        velocity: sequence[float64]
        effort: sequence[float64]

    topic, cloud = read_cloud(args.bag)
    topic = args.topic or topic
    frame = cloud.header.frame_id
    width, height = cloud.width, cloud.height
    header = lambda stamp_ns: Header_(Time_(stamp_ns // 10**9, stamp_ns % 10**9), frame)
    domain = int(os.environ.get("ROS_DOMAIN_ID", "0"))
    sensor = Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(1))
    if args.transport == "dds":
        dp = DomainParticipant(domain)

        def DataWriter(_, t, qos):  # noqa: N802 (the DDS writer, or the zenoh one below)
            return CycloneWriter(dp, t, qos=qos)

        def Topic(_, name, ty):  # noqa: N802
            return CycloneTopic(dp, name, ty)
    else:
        import zenoh

        if args.zenoh_config:
            conf = zenoh.Config.from_file(args.zenoh_config)
        else:
            conf = zenoh.Config()
            conf.insert_json5("mode", '"peer"')
            conf.insert_json5("connect/endpoints", json.dumps([args.connect]))
            conf.insert_json5("scouting/multicast/enabled", "false")
        for entry in filter(None, (e.strip() for e in args.zenoh_override.split(";"))):
            k, v = entry.split("=", 1)
            conf.insert_json5(k.strip(), v.strip())
        session = zenoh.open(conf)
        gid = os.urandom(16)
        dp = None

        # The RIHS01 type hashes of ROS 2 Jazzy, as an rmw_zenoh camera driver keys its topics.
        hashes = {
            "PointCloud2_":
                "RIHS01_9198cabf7da3796ae6fe19c4cb3bdd3525492988c70522628af5daa124bae2b5",
            "Image_": "RIHS01_d31d41a9a4c4bc8eae9be757b0beed306564f7526c88ea6a4588fb9582527d47",
            "CameraInfo_":
                "RIHS01_b3dfd68ff46c9d56c80fd3bd4ed22c7a4ddce8c8348f2f59c299e73118e7e275",
        }

        class ZenohWriter:
            def __init__(self, name, ty):
                dds = ty.__idl_typename__
                key = f"{domain}/{name[3:]}/{dds}/{hashes[dds.rsplit('::', 1)[1]]}"
                self.publisher = session.declare_publisher(key)
                self.seq = 0

            def write(self, sample):
                self.seq += 1
                payload = sample.serialize()  # plain CDR, little endian, with its header
                attachment = struct.pack("<qq16s", self.seq, time.time_ns(), gid)
                self.publisher.put(payload, attachment=attachment)

        def DataWriter(_, t, qos):  # noqa: N802
            return ZenohWriter(*t)

        def Topic(_, name, ty):  # noqa: N802
            return (name, ty)
    info = {"mode": args.mode, "rate_hz": args.rate, "width": width, "height": height}
    if args.mode == "cloud":
        fields = [PointField_(f.name, f.offset, f.datatype, f.count) for f in cloud.fields]
        payload = bytes(cloud.data)
        writer = DataWriter(dp, Topic(dp, "rt" + topic, PointCloud2_), qos=sensor)
        info.update(topic=topic, bytes=len(payload))

        def publish(stamp_ns):
            writer.write(PointCloud2_(header(stamp_ns), height, width, fields,
                                      bool(cloud.is_bigendian), cloud.point_step,
                                      cloud.row_step, payload, bool(cloud.is_dense)))
    else:
        payload, (fx, fy, cx, cy, res), image_topic, info_topic = depth_of(cloud, topic)
        image_writer = DataWriter(dp, Topic(dp, "rt" + image_topic, Image_), qos=sensor)
        info_writer = DataWriter(dp, Topic(dp, "rt" + info_topic, CameraInfo_), qos=sensor)
        k = [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0]
        p = [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0]
        info.update(topic=image_topic, camera_info_topic=info_topic, bytes=len(payload),
                    fx=fx, fy=fy, cx=cx, cy=cy, fit_rms_px=res)

        def publish(stamp_ns):
            h = header(stamp_ns)
            info_writer.write(CameraInfo_(h, height, width, "plumb_bob", [0.0] * 5, k,
                                          [1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0], p, 0, 0,
                                          RegionOfInterest_(0, 0, 0, 0, False)))
            image_writer.write(Image_(h, height, width, "16UC1", 0, 2 * width, payload))

    sent = {}
    latencies = []
    lock = threading.Lock()
    done = threading.Event()

    handed = {}  # stamp -> when write/put returned
    after_handover = []  # ms from then to the answer: the middleware's and the node's share

    def answered(stamp):
        now = time.monotonic()
        with lock:
            at = sent.pop(stamp, None)
            out = handed.pop(stamp, None)
        if at is not None:
            latencies.append((now - at) * 1e3)
        if out is not None:
            after_handover.append((now - out) * 1e3)

    if args.transport == "dds":
        reader = DataReader(dp, CycloneTopic(dp, "rt" + args.node + "/link_distances", JointState_),
                            qos=Qos(Policy.Reliability.Reliable(1), Policy.History.KeepLast(100)))

        def listen():
            while not done.is_set():
                for m in reader.take(N=100):
                    answered(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec)
                time.sleep(0.0005)
    else:
        def on_sample(sample):
            # sensor_msgs/JointState CDR: the header's stamp first (sec int32, nanosec uint32).
            sec, nanosec = struct.unpack_from("<iI", bytes(sample.payload.to_bytes()), 4)
            answered(sec * 10**9 + nanosec)

        subscriber = session.declare_subscriber(
            f"{domain}/{args.node.strip('/')}/link_distances/**", on_sample)

        def listen():
            done.wait()

    listener = threading.Thread(target=listen)
    listener.start()
    time.sleep(args.wait)
    count, publishing = paced(args, publish, lock, sent, handed)
    time.sleep(1.0)
    done.set()
    listener.join()
    lat = sorted(latencies)
    q = lambda f: round(lat[min(len(lat) - 1, int(f * len(lat)))], 2) if lat else None
    info.update(published=count, answered=len(lat), p50_ms=q(0.5), p99_ms=q(0.99),
                max_ms=round(lat[-1], 2) if lat else None)
    pub = sorted(publishing)
    rest = sorted(after_handover)
    share = lambda v, f: round(v[min(len(v) - 1, int(f * len(v)))], 2) if v else None
    info.update(publish_p50_ms=share(pub, 0.5), publish_p99_ms=share(pub, 0.99),
                after_publish_p50_ms=share(rest, 0.5), after_publish_p99_ms=share(rest, 0.99))
    print(json.dumps(info), flush=True)
    if args.transport == "zenoh":
        subscriber.undeclare()
        session.close()


if __name__ == "__main__":
    main()
