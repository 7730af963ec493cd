"""Interop with an independent DDS implementation: Eclipse Cyclone DDS (the `cyclonedds`
package) talks to ist_monitor under the ROS 2 naming, as a standard ROS 2 node would.

    cyclonedds_interop.py [URDF]
                            publish the URDF file's text (mesh paths made absolute) on
                            rt/robot_description as std_msgs/String, reliable and transient
                            local as robot_state_publisher does; then a sensor_msgs/PointCloud2
                            on rt/camera/depth/points (frame camera_link, one plane of points in
                            front of the camera) at 10 Hz, and print, as JSON, the first
                            std_msgs/Float64 received on rt/ist_monitor/min_distance (or null
                            after 30 s); then, read with the QoS joint_trajectory_controller's
                            ~/speed_scaling_input asks (reliable, transient local, keep last 1),
                            the control_msgs/SpeedScalingFactor on
                            rt/joint_trajectory_controller/speed_scaling_input (where the node is
                            remapped to publish it) until its factor reaches 0.2 (or 10 s pass):
                            the last one received
    cyclonedds_interop.py --watch S
                            as above without the robot description; then prints `watching` and
                            goes on publishing the cloud for S seconds while it records every
                            std_msgs/Bool on rt/ist_monitor/safety_stop and every factor; the
                            JSON then also has "stops" and "factors", in the order received
                            (what a controller and a safety PLC saw last when the node stopped)
    cyclonedds_interop.py --watch S --deadline D --lease L
                            also reads rt/ist_monitor/safety_stop with a requested QoS deadline
                            of D seconds and automatic liveliness of lease L seconds (matched
                            only if the node offers D and L or less); the JSON then also has
                            "deadline_samples" (what that reader received), "deadline_missed"
                            (the wall-clock times, s since the epoch, at which Cyclone DDS
                            reported a missed deadline) and "liveliness" ([time, alive writers]
                            at each change Cyclone DDS reported)
"""
import os
import sys
import json
import struct
import time
from dataclasses import dataclass

from cyclonedds.core import Listener, Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import float64, int32, sequence, uint8, uint32
from cyclonedds.util import duration
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic


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
class Float64_(IdlStruct, typename="std_msgs::msg::dds_::Float64_"):
    data: float64


@dataclass
class SpeedScalingFactor_(IdlStruct, typename="control_msgs::msg::dds_::SpeedScalingFactor_"):
    factor: float64


@dataclass
class Bool_(IdlStruct, typename="std_msgs::msg::dds_::Bool_"):
    data: bool


@dataclass
class String_(IdlStruct, typename="std_msgs::msg::dds_::String_"):
    data: str


def cloud():
    # camera_link is x forward: a 20 × 20 patch 0.6 m ahead of the camera.
    points = [(0.6, -0.2 + 0.02 * i, -0.2 + 0.02 * j) for i in range(20) for j in range(20)]
    data = b"".join(struct.pack("<fffI", x, y, z, 0) for x, y, z in points)
    now = time.time()
    fields = [PointField_(n, o, 7, 1) for n, o in (("x", 0), ("y", 4), ("z", 8))]
    return PointCloud2_(
        header=Header_(Time_(int(now), int((now % 1) * 1e9)), "camera_link"),
        height=1, width=len(points), fields=fields, is_bigendian=False,
        point_step=16, row_step=16 * len(points), data=list(data), is_dense=True)


def main():
    dp = DomainParticipant(0)
    args = sys.argv[1:]
    watch = None
    if "--watch" in args:
        i = args.index("--watch")
        watch = float(args[i + 1])
        del args[i:i + 2]
    deadline_s = lease_s = None
    for flag in ("--deadline", "--lease"):
        if flag in args:
            i = args.index(flag)
            value = float(args[i + 1])
            del args[i:i + 2]
            if flag == "--deadline":
                deadline_s = value
            else:
                lease_s = value
    if args:
        urdf = os.path.abspath(args[0])
        text = open(urdf).read().replace('filename="meshes/',
                                         f'filename="file://{os.path.dirname(urdf)}/meshes/')
        description = DataWriter(dp, Topic(dp, "rt/robot_description", String_), qos=Qos(
            Policy.Reliability.Reliable(max_blocking_time=1),
            Policy.Durability.TransientLocal, Policy.History.KeepLast(1)))
        description.write(String_(text))
    cloud_topic = Topic(dp, "rt/camera/depth/points", PointCloud2_)
    writer = DataWriter(dp, cloud_topic, qos=Qos(Policy.Reliability.BestEffort))
    out_topic = Topic(dp, "rt/ist_monitor/min_distance", Float64_)
    reader = DataReader(dp, out_topic, qos=Qos(Policy.Reliability.Reliable(max_blocking_time=1)))
    stop_reader = DataReader(dp, Topic(dp, "rt/ist_monitor/safety_stop", Bool_), qos=Qos(
        Policy.Reliability.Reliable(max_blocking_time=1), Policy.History.KeepLast(1000)))
    missed = []
    liveliness = []
    deadline_reader = None
    if deadline_s is not None:
        deadline_reader = DataReader(
            dp, Topic(dp, "rt/ist_monitor/safety_stop", Bool_), qos=Qos(
                Policy.Reliability.Reliable(max_blocking_time=1), Policy.History.KeepLast(1000),
                Policy.Deadline(duration(seconds=deadline_s)),
                Policy.Liveliness.Automatic(lease_duration=duration(seconds=lease_s or 3600))),
            listener=Listener(
                on_requested_deadline_missed=lambda r, s: missed.append(time.time()),
                on_liveliness_changed=lambda r, s: liveliness.append(
                    [time.time(), s.alive_count])))
    deadline = time.time() + 30
    received = None
    while time.time() < deadline and received is None:
        writer.write(cloud())
        time.sleep(0.1)
        for sample in reader.take(N=10):
            received = sample.data
    scaling = DataReader(dp, Topic(
        dp, "rt/joint_trajectory_controller/speed_scaling_input", SpeedScalingFactor_),
                         qos=Qos(Policy.Reliability.Reliable(max_blocking_time=1),
                                 Policy.Durability.TransientLocal, Policy.History.KeepLast(1)))
    factor = None
    deadline = time.time() + 10
    while received is not None and time.time() < deadline and (factor or 0.0) < 0.2:
        writer.write(cloud())
        time.sleep(0.1)
        for sample in scaling.take(N=10):
            factor = sample.factor
    out = {"min_distance": received, "speed_scaling": factor}
    if watch is not None:
        # A writer that leaves sends an invalid sample (no data): not a message.
        stops = [s.data for s in stop_reader.take(N=1000) if isinstance(s, Bool_)]
        factors = [factor] if factor is not None else []
        print("watching", flush=True)
        end = time.time() + watch
        while time.time() < end:
            writer.write(cloud())
            time.sleep(0.1)
            stops += [s.data for s in stop_reader.take(N=1000) if isinstance(s, Bool_)]
            factors += [
                s.factor for s in scaling.take(N=100) if isinstance(s, SpeedScalingFactor_)
            ]
        out["stops"] = stops
        out["factors"] = factors
        if deadline_reader is not None:
            out["deadline_samples"] = len(
                [s for s in deadline_reader.take(N=100000) if isinstance(s, Bool_)])
            out["deadline_missed"] = missed
            out["liveliness"] = liveliness
    print(json.dumps(out))


if __name__ == "__main__":
    main()
