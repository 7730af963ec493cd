"""Interop with the real ROS 2 client: rclpy on rmw_fastrtps_cpp (Fast DDS, ROS 2 Jazzy's default
middleware, installed from the package index) talks to a running ist_monitor as `ros2 param` and
any ROS 2 node would.

    rclpy_interop.py params NODE
        NODE is the monitor's fully qualified name (/ist_monitor). Through its rcl_interfaces
        services: lists, describes and gets its parameters; sets a read-only one and a
        weakening one while the safety stop is raised (no cloud yet: both must be refused);
        then publishes a sensor_msgs/PointCloud2 on /camera/depth/points at 10 Hz (frame
        camera_link, a 20 x 20 plane 0.6 m ahead of the camera) and, once the fused status on
        /diagnostics is OK, adds the exclusion volume `patch` (a box around half the plane)
        with set_parameters_atomically, reads `points_excluded.patch` from /diagnostics,
        raises stop_distance and removes the volume; disables the camera (nothing watches: the
        fused status must turn ERROR) and enables it again (OK again once its clouds are
        heard); attaches a box `shield` to camera_link around half the plane (the fused status
        must name link shield, the rest of the plane a few cm from it) and releases it. Records
        every /parameter_events message of NODE. Prints one JSON object with
        every answer.

    rclpy_interop.py rule NODE
        Publishes the plane as `params` does until NODE's fused status is OK (the stop
        released); then gets parameter_changes, sets stop_distance to 0.05 (lower) and to 0.2
        (higher) and gets it. Prints one JSON object.

    rclpy_interop.py sim NODE TOPIC
        NODE started as a launch file starts it, with use_sim_time and its cloud source remapped
        to TOPIC. Gets stop_distance, use_sim_time and backend; waits for the fused status to
        be ERROR naming /clock (nothing on /clock yet); then publishes rosgraph_msgs/Clock on
        /clock (simulated time from 1000 s, at the wall clock's pace, 100 Hz) and the plane on
        TOPIC stamped with it, and waits for OK (a cloud stamped 1000 s is only fresh by the
        simulated clock), reading the stamp of the node's /diagnostics; stops /clock (the
        clouds go on) and waits for ERROR naming /clock again; restarts it at 500 s (a bag
        played again) and waits for OK. Prints one JSON object.

    rclpy_interop.py answers NODE TOPIC MESSAGE_CDR [CAMERA_INFO_CDR]
        Publishes the message in MESSAGE_CDR (a serialized sensor_msgs/PointCloud2, or with
        CAMERA_INFO_CDR a sensor_msgs/Image with its CameraInfo, published beside it on
        camera_info) on TOPIC at 10 Hz, stamped now, until NODE has answered 10 of them on
        ~/min_distance; records the last ~/min_distance, ~/closest_points and the fused
        /diagnostics status; then stops publishing and waits for the fused status to turn ERROR
        (the source's timeout). Also lists the nodes and NODE's topics as the graph shows them,
        and NODE's lines on /rosout.
        Prints one JSON object.

    rclpy_interop.py voices NODE TOPIC NEAR_CDR FAR_CDR MODE [JOINTS_JSON]
        One voice per source (issue 46). A camera node publishes the serialized PointCloud2 in
        NEAR_CDR on TOPIC at 10 Hz, stamped now, with best-effort sensor QoS; once the fused
        status is ERROR with a distance (the obstacle measured) and NODE/safety_stop raised, a
        second participant (another rclpy context: another DDS participant, as a second driver
        or anyone on the network would be) makes a publisher on the same topic and publishes
        FAR_CDR with it 50 ms after each near one, for 4 s, then destroys it. MODE interleaved:
        as said; camera_lost: the camera publishes nothing while the second one speaks (its
        clouds all lost). With JOINTS_JSON ({"names": [...], "positions": [...], "intruder":
        [...]}) the controller (the camera's participant) also publishes /joint_states at 50 Hz,
        and the second participant publishes the intruder's positions on /joint_states instead
        of the far cloud (camera_lost: the controller's joint states are the ones lost). Records every NODE/safety_stop with the phase it came in, and the
        /diagnostics messages. Prints one JSON object: "raised" (the stop was raised before the
        intruder), "during" and "after" (the stops received while the intruder spoke and after
        it), "messages" (the messages of the statuses above OK seen while it spoke;
        "late_messages" those from 2 s after it began, twice the voice window),
        "measured_after" (the obstacle measured again, within 20 s, once it was gone).
"""
import json
import math
import struct
import sys
import threading
import time

import rclpy
from rclpy.executors import MultiThreadedExecutor
from rclpy.qos import qos_profile_sensor_data

from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import Parameter, ParameterEvent, ParameterType, ParameterValue
from rcl_interfaces.srv import (DescribeParameters, GetParameters, GetParameterTypes,
                                ListParameters, SetParameters, SetParametersAtomically)
from sensor_msgs.msg import PointCloud2, PointField


def value(v):
    """A Python value as a ParameterValue, typed as `ros2 param set` types it."""
    if isinstance(v, bool):
        return ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=v)
    if isinstance(v, int):
        return ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=v)
    if isinstance(v, float):
        return ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=v)
    if isinstance(v, str):
        return ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=v)
    if all(isinstance(x, str) for x in v):
        return ParameterValue(type=ParameterType.PARAMETER_STRING_ARRAY, string_array_value=v)
    return ParameterValue(type=ParameterType.PARAMETER_DOUBLE_ARRAY,
                          double_array_value=[float(x) for x in v])


def plain(v):
    """A ParameterValue as a Python value (None: not set)."""
    t = v.type
    return {
        ParameterType.PARAMETER_NOT_SET: lambda: None,
        ParameterType.PARAMETER_BOOL: lambda: v.bool_value,
        ParameterType.PARAMETER_INTEGER: lambda: v.integer_value,
        ParameterType.PARAMETER_DOUBLE: lambda: v.double_value,
        ParameterType.PARAMETER_STRING: lambda: v.string_value,
        ParameterType.PARAMETER_DOUBLE_ARRAY: lambda: list(v.double_array_value),
        ParameterType.PARAMETER_INTEGER_ARRAY: lambda: list(v.integer_array_value),
        ParameterType.PARAMETER_STRING_ARRAY: lambda: list(v.string_array_value),
        ParameterType.PARAMETER_BOOL_ARRAY: lambda: list(v.bool_array_value),
    }[t]()


def finite(x):
    """A float as JSON has it (an infinity as the string "inf")."""
    return x if math.isfinite(x) else str(x)


def cloud(stamp):
    points = [(0.6, -0.2 + 0.02 * i, -0.2 + 0.02 * j) for i in range(20) for j in range(20)]
    m = PointCloud2()
    m.header.stamp = stamp
    m.header.frame_id = "camera_link"
    m.height, m.width = 1, len(points)
    m.fields = [PointField(name=n, offset=o, datatype=PointField.FLOAT32, count=1)
                for n, o in (("x", 0), ("y", 4), ("z", 8))]
    m.is_bigendian, m.point_step, m.row_step, m.is_dense = False, 12, 12 * len(points), True
    m.data = b"".join(struct.pack("<fff", *p) for p in points)
    return m


def spin(name):
    """rclpy started and a node `name` spun by a thread of its own: (node, executor)."""
    rclpy.init()
    node = rclpy.create_node(name)
    executor = MultiThreadedExecutor()
    executor.add_node(node)
    executor.spinner = threading.Thread(target=executor.spin, daemon=True)
    executor.spinner.start()
    return node, executor


def shut(node, executor):
    """Stops the spinning thread before rclpy goes (a thread still in rclpy's wait when the
    interpreter exits aborts the process)."""
    executor.shutdown()
    executor.spinner.join()
    node.destroy_node()
    rclpy.shutdown()


def waiter(lock):
    """wait_for(what, timeout): True once `what()` (called under `lock`) is, False after
    `timeout` seconds."""
    def wait_for(what, timeout):
        deadline = time.time() + timeout
        while time.time() < deadline:
            with lock:
                if what():
                    return True
            time.sleep(0.05)
        return False
    return wait_for


def watch_fused(node, lock):
    """A dict that follows the monitor's fused status on /diagnostics (under `lock`): level,
    message, link, distance_m and the array's stamp in seconds."""
    fused = {"level": None, "message": "", "link": None, "distance_m": None, "stamp": None}

    def on_diagnostics(m):
        for s in m.status:
            if s.name.endswith(": all sources"):
                values = {kv.key: kv.value for kv in s.values}
                with lock:
                    fused.update(
                        level=s.level[0] if isinstance(s.level, bytes) else s.level,
                        message=s.message, link=values.get("link"),
                        distance_m=(float(values["distance_m"]) if "distance_m" in values
                                    else None),
                        stamp=m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec)

    node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 10)
    return fused


def services(node, node_name):
    """(call, set_, get) on NODE's rcl_interfaces services: call(srv, service, **fields) the
    response; set_(service, **values) each result's successful and reason (`a__b` names `a.b`);
    get(*names) the values."""
    def call(srv, service, **fields):
        client = node.create_client(srv, f"{node_name}/{service}")
        if not client.wait_for_service(timeout_sec=30):
            raise SystemExit(f"{node_name}/{service}: no service after 30 s")
        request = srv.Request()
        for k, v in fields.items():
            setattr(request, k, v)
        response = client.call(request, timeout_sec=10)
        if response is None:
            raise SystemExit(f"{node_name}/{service}: no answer in 10 s")
        return response

    def set_(service, **values):
        ps = [Parameter(name=k.replace("__", "."), value=value(v)) for k, v in values.items()]
        if service == "set_parameters_atomically":
            r = call(SetParametersAtomically, service, parameters=ps).result
            return {"successful": r.successful, "reason": r.reason}
        return [{"successful": r.successful, "reason": r.reason}
                for r in call(SetParameters, service, parameters=ps).results]

    def get(*names):
        return [plain(v) for v in call(GetParameters, "get_parameters", names=list(names)).values]

    return call, set_, get


def rule(node_name):
    """`rule NODE`: publishes the plane as `params` does until the fused status is OK (the stop
    released), then reads parameter_changes and asks NODE to lower stop_distance to 0.05 and
    to raise it to 0.2. Prints one JSON object."""
    node, executor = spin("rclpy_rule")
    lock = threading.Lock()
    fused = watch_fused(node, lock)
    _, set_, get = services(node, node_name)
    publisher = node.create_publisher(PointCloud2, "/camera/depth/points", qos_profile_sensor_data)
    node.create_timer(0.1, lambda: publisher.publish(cloud(node.get_clock().now().to_msg())))
    out = {"released": waiter(lock)(lambda: fused["level"] == 0, 20)}
    out["rule"] = get("parameter_changes")[0]
    out["lower"] = set_("set_parameters", stop_distance=0.05)[0]
    out["raise"] = set_("set_parameters", stop_distance=0.2)[0]
    out["stop_distance"] = get("stop_distance")[0]
    print(json.dumps(out))
    shut(node, executor)


def params(node_name):
    node, executor = spin("rclpy_interop")
    out = {"events": []}
    lock = threading.Lock()
    fused = {"level": None, "excluded": None, "link": None, "distance_m": None}

    def on_event(e):
        if e.node == node_name:
            with lock:
                out["events"].append({
                    "new": [p.name for p in e.new_parameters],
                    "changed": {p.name: plain(p.value) for p in e.changed_parameters},
                    "deleted": [p.name for p in e.deleted_parameters],
                })

    def on_diagnostics(m):
        for s in m.status:
            if s.name.endswith(": all sources"):
                values = {kv.key: kv.value for kv in s.values}
                with lock:
                    fused["level"] = s.level[0] if isinstance(s.level, bytes) else s.level
                    fused["link"] = values.get("link")
                    fused["distance_m"] = float(values["distance_m"]) if "distance_m" in values else None
            for kv in s.values:
                if kv.key == "points_excluded.patch":
                    with lock:
                        fused["excluded"] = int(kv.value)

    node.create_subscription(ParameterEvent, "/parameter_events", on_event, 1000)
    node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 10)

    call, set_, get = services(node, node_name)

    wait_for = waiter(lock)

    def set_released(**values):
        """A change that weakens protection, made while the stop is released: refused while it is
        raised, so asked again once the cell is OK again (on 2 busy cores this rclpy camera's
        clouds can pause for more than source_timeout, which raises the stop in between), for at
        most 30 s. Every refusal must be for the raised stop."""
        deadline = time.monotonic() + 30
        while True:
            wait_for(lambda: fused["level"] == 0, max(0.1, deadline - time.monotonic()))
            r = set_("set_parameters_atomically", **values)
            if r["successful"] or "safety stop is raised" not in r["reason"] \
                    or time.monotonic() > deadline:
                return r

    out["list"] = list(call(ListParameters, "list_parameters").result.names)
    out["types"] = list(call(GetParameterTypes, "get_parameter_types",
                             names=["stop_distance", "release_frames", "mode", "sources"]).types)
    out["describe"] = [
        {"name": d.name, "type": d.type, "description": d.description,
         "constraints": d.additional_constraints, "read_only": d.read_only,
         "range": [[finite(r.from_value), finite(r.to_value)] for r in d.floating_point_range]}
        for d in call(DescribeParameters, "describe_parameters",
                      names=["stop_distance", "mode"]).descriptors]
    out["get"] = get("stop_distance", "release_frames", "sources", "camera.topic")
    # No cloud yet: the camera is in fault, the stop raised.
    out["set_read_only"] = set_("set_parameters", mode="exact")
    out["set_weakening_while_stopped"] = set_("set_parameters", stop_distance=0.05)

    publisher = node.create_publisher(PointCloud2, "/camera/depth/points", qos_profile_sensor_data)
    node.create_timer(0.1, lambda: publisher.publish(cloud(node.get_clock().now().to_msg())))
    out["released"] = wait_for(lambda: fused["level"] == 0, 20)
    out["add_volume"] = set_released(exclusion_volumes=["patch"], patch__frame="camera_link",
                                     patch__size=[0.1, 0.2, 0.5],
                                     patch__translation=[0.6, -0.11, 0.0])
    wait_for(lambda: fused["excluded"] is not None, 10)
    out["points_excluded"] = fused["excluded"]
    out["get_volume"] = get("exclusion_volumes", "patch.size", "patch.shape")
    out["raise_stop"] = set_("set_parameters", stop_distance=0.25)
    out["remove_volume"] = set_("set_parameters", exclusion_volumes=[])
    out["after"] = get("stop_distance", "exclusion_volumes", "patch.size")
    # The only source disabled (the stop is released: taken): nothing watches, a fault. Enabled
    # again (always taken): the node subscribes anew and the cloud releases the stop.
    out["disable"] = set_("set_parameters", camera__enabled=False)
    with lock:
        fused["level"] = None
    out["nothing_watches"] = wait_for(lambda: fused["level"] == 2, 5)
    out["enable"] = set_("set_parameters", camera__enabled=True)
    with lock:
        fused["level"] = None
    out["released_again"] = wait_for(lambda: fused["level"] == 0, 10)
    # A shield attached to camera_link around the same half of the plane: its points are the
    # robot's now, and the rest of the plane, a few cm from it, is measured to it (ERROR, link
    # shield). Released: the plane is far again.
    started = time.time()
    out["attach"] = set_released(attached_objects=["shield"], shield__link="camera_link",
                                 shield__size=[0.1, 0.2, 0.5],
                                 shield__translation=[0.6, -0.11, 0.0])
    out["shield_nearest"] = wait_for(lambda: fused["link"] == "shield", 60)
    out["attach_s"] = time.time() - started
    with lock:
        out["shield_status"] = {"level": fused["level"], "distance_m": fused["distance_m"]}
    out["detach"] = set_("set_parameters", attached_objects=[])
    with lock:
        fused["level"] = None
    out["released_after_detach"] = wait_for(
        lambda: fused["level"] == 0 and fused["link"] != "shield", 60)
    time.sleep(0.5)
    with lock:
        print(json.dumps(out))
    shut(node, executor)


def sim(node_name, topic):
    from builtin_interfaces.msg import Time
    from rosgraph_msgs.msg import Clock
    node, executor = spin("rclpy_sim_time")
    lock = threading.Lock()
    fused = watch_fused(node, lock)
    out = {}

    wait_for = waiter(lock)

    client = node.create_client(GetParameters, f"{node_name}/get_parameters")
    if not client.wait_for_service(timeout_sec=30):
        raise SystemExit(f"{node_name}/get_parameters: no service after 30 s")
    answer = client.call(GetParameters.Request(
        names=["stop_distance", "use_sim_time", "backend", "warn_distance"]), timeout_sec=10)
    out["get"] = [plain(v) for v in answer.values]
    out["waits_for_clock"] = wait_for(
        lambda: fused["level"] == 2 and "/clock" in fused["message"], 30)
    out["waiting_message"] = fused["message"]

    sim_time = {"origin": 1000.0, "wall": time.time(), "running": True}

    def now():
        with lock:
            t = sim_time["origin"] + time.time() - sim_time["wall"]
        return Time(sec=int(t), nanosec=int((t % 1) * 1e9))

    clock_pub = node.create_publisher(Clock, "/clock", 10)
    cloud_pub = node.create_publisher(PointCloud2, topic, qos_profile_sensor_data)

    def tick():
        with lock:
            running = sim_time["running"]
        if running:
            clock_pub.publish(Clock(clock=now()))

    node.create_timer(0.01, tick)
    node.create_timer(0.1, lambda: cloud_pub.publish(cloud(now())))
    out["ok_on_sim_time"] = wait_for(lambda: fused["level"] == 0, 30)
    with lock:
        out["stamp_s"] = fused["stamp"]
    # The simulation stops: /clock silent, the clouds go on.
    with lock:
        sim_time["running"] = False
    out["silent_clock"] = wait_for(
        lambda: fused["level"] == 2 and "/clock is silent" in fused["message"], 10)
    out["silent_message"] = fused["message"]
    # A bag played again: the clock restarts, 500 s back.
    with lock:
        sim_time.update(origin=500.0, wall=time.time(), running=True)
        fused["level"] = None
    out["ok_after_jump"] = wait_for(lambda: fused["level"] == 0, 30)
    with lock:
        out["stamp_after_jump_s"] = fused["stamp"]
    print(json.dumps(out))
    shut(node, executor)


def answers(node_name, topic, message_file, info_file):
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import CameraInfo, Image
    from std_msgs.msg import Float64
    from visualization_msgs.msg import MarkerArray
    node, executor = spin("rclpy_answers")
    lock = threading.Lock()
    seen = watch_fused(node, lock)
    seen.update(min_distance=[], markers=None)

    def on_min(m):
        with lock:
            seen["min_distance"].append(m.data)

    def on_markers(m):
        with lock:
            seen["markers"] = [[[p.x, p.y, p.z] for p in k.points] for k in m.markers
                               if k.points]

    from rcl_interfaces.msg import Log
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    logger = node_name.strip("/").replace("/", ".")
    rosout = []

    def on_log(m):
        if m.name == logger:
            with lock:
                rosout.append({"level": m.level, "msg": m.msg, "function": m.function})

    node.create_subscription(Log, "/rosout", on_log, QoSProfile(
        depth=1000, reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL))
    node.create_subscription(Float64, f"{node_name}/min_distance", on_min, 10)
    node.create_subscription(MarkerArray, f"{node_name}/closest_points", on_markers, 10)
    with open(message_file, "rb") as f:
        raw = f.read()
    if info_file:
        message = deserialize_message(raw, Image)
        with open(info_file, "rb") as f:
            info = deserialize_message(f.read(), CameraInfo)
        info_pub = node.create_publisher(
            CameraInfo, topic.rsplit("/", 1)[0] + "/camera_info", qos_profile_sensor_data)
        pub = node.create_publisher(Image, topic, qos_profile_sensor_data)
    else:
        message, info, info_pub = deserialize_message(raw, PointCloud2), None, None
        pub = node.create_publisher(PointCloud2, topic, qos_profile_sensor_data)
    running = {"on": True}

    def publish():
        if not running["on"]:
            return
        stamp = node.get_clock().now().to_msg()
        message.header.stamp = stamp
        if info is not None:
            info.header.stamp = stamp
            info_pub.publish(info)
        pub.publish(message)

    node.create_timer(0.1, publish)

    wait_for = waiter(lock)

    out = {"answered": wait_for(lambda: len(seen["min_distance"]) >= 10, 60)}
    # A measured picture (markers drawn, no fault), taken at once: a late frame of this
    # publisher (a slow machine) would turn the cell to ERROR for a moment, as it should.
    wait_for(lambda: seen["markers"] and seen["level"] in (0, 1), 10)
    with lock:
        out.update(min_distance=seen["min_distance"][-1] if seen["min_distance"] else None,
                   markers=seen["markers"], level=seen["level"], link=seen["link"],
                   distance_m=seen["distance_m"])
    # The node in the graph, its outputs with their types.
    out["nodes"] = [f"{ns.rstrip('/')}/{n}" for n, ns in node.get_node_names_and_namespaces()]
    out["topics"] = {t: types for t, types in node.get_topic_names_and_types()
                     if t.startswith(node_name + "/") or t == "/diagnostics"}
    running["on"] = False
    out["error_after_last"] = wait_for(lambda: seen["level"] == 2, 10)
    out["error_message"] = seen["message"]
    with lock:
        out["rosout"] = rosout
    print(json.dumps(out))
    shut(node, executor)


def stamped(raw, now_ns):
    """A serialized message with its header stamp (just after the 4-byte CDR encapsulation,
    little endian) set to `now_ns`."""
    out = bytearray(raw)
    struct.pack_into("<iI", out, 4, now_ns // 1_000_000_000, now_ns % 1_000_000_000)
    return bytes(out)


def voices(node_name, topic, near_file, far_file, mode, joints_json):
    """A second writer on the camera's topic (or on /joint_states with `joints_json`), in its
    own participant, from the moment the node has measured the obstacle and raised the stop
    until it is destroyed 4 s later. `mode` interleaved: the camera publishes the near cloud at
    10 Hz and the intruder the far one 50 ms after each; camera_lost: the first writer's messages
    on the contested topic (the camera's clouds, or with `joints_json` the controller's joint
    states) are all lost while the intruder speaks (it publishes none). Prints the stops before, during and
    after, the diagnostics' messages during, and whether the camera alone was measured again."""
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Bool
    node, executor = spin("rclpy_camera")
    # The intruder: a participant of its own.
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    intruder = rclpy.create_node("rclpy_intruder", context=ctx)
    intruder_exec = SingleThreadedExecutor(context=ctx)
    intruder_exec.add_node(intruder)
    threading.Thread(target=intruder_exec.spin, daemon=True).start()
    lock = threading.Lock()
    fused = watch_fused(node, lock)
    state = {"phase": "before", "stops": {"before": [], "during": [], "after": []},
             "messages": set(), "late": set(), "since": None}

    def on_stop(m):
        with lock:
            state["stops"][state["phase"]].append(bool(m.data))

    def on_diagnostics(m):
        with lock:
            if state["phase"] == "during":
                said = [s.message for s in m.status if s.level != b"\x00"]
                state["messages"].update(said)
                # Past twice the voice window (1 s): what the messages alone no longer say.
                if time.monotonic() - state["since"] > 2.0:
                    state["late"].update(said)

    node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 10)
    node.create_subscription(Bool, f"{node_name}/safety_stop", on_stop,
                             QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))
    with open(near_file, "rb") as f:
        near = f.read()
    with open(far_file, "rb") as f:
        far = f.read()
    joints = json.loads(joints_json) if joints_json else None
    camera = node.create_publisher(PointCloud2, topic, qos_profile_sensor_data)
    js_pub = node.create_publisher(JointState, "/joint_states", qos_profile_sensor_data)
    running = {"on": True, "intruder": None}

    def joint_state(pub, positions):
        m = JointState()
        m.header.stamp = node.get_clock().now().to_msg()
        m.name, m.position = joints["names"], [float(p) for p in positions]
        pub.publish(m)

    def publish_loop():
        k = 0
        while running["on"]:
            now = time.time_ns()
            second = running["intruder"]
            # camera_lost: the first writer's messages on the contested topic are all lost.
            lost = bool(second) and mode == "camera_lost"
            if k % 5 == 0 and not (lost and not joints):
                camera.publish(stamped(near, now))
            if joints and not lost:
                joint_state(js_pub, joints["positions"])
            time.sleep(0.01)
            if second:
                if joints:
                    joint_state(second, joints["intruder"])
                elif k % 5 == 0:
                    time.sleep(0.04)
                    second.publish(stamped(far, time.time_ns()))
            k += 1
            time.sleep(max(0.0, 0.02 - (time.time_ns() - now) * 1e-9))

    thread = threading.Thread(target=publish_loop, daemon=True)
    thread.start()
    wait_for = waiter(lock)
    # Raised by the measured obstacle (not by the start: the node is not monitoring until its
    # trees are built).
    out = {"raised": wait_for(lambda: fused["level"] == 2 and fused["distance_m"] is not None
                              and True in state["stops"]["before"], 120),
           "distance_m": fused["distance_m"]}
    with lock:
        state["phase"] = "during"
        state["since"] = time.monotonic()
    second = (intruder.create_publisher(JointState, "/joint_states", qos_profile_sensor_data)
              if joints else
              intruder.create_publisher(PointCloud2, topic, qos_profile_sensor_data))
    running["intruder"] = second
    time.sleep(4.0)
    running["intruder"] = None
    time.sleep(0.1)
    intruder.destroy_publisher(second)
    with lock:
        state["phase"] = "after"
        fused["distance_m"] = None
    # The camera alone again: measured once the intruder is gone from discovery and its last
    # message is a window old.
    out["measured_after"] = wait_for(lambda: fused["level"] == 2
                                     and fused["distance_m"] is not None, 20)
    time.sleep(0.5)
    running["on"] = False
    thread.join()
    with lock:
        out.update(during=state["stops"]["during"], after=state["stops"]["after"],
                   messages=sorted(state["messages"]), late_messages=sorted(state["late"]))
    print(json.dumps(out))
    intruder_exec.shutdown()
    intruder.destroy_node()
    rclpy.shutdown(context=ctx)
    shut(node, executor)


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "params":
        params(sys.argv[2])
    elif len(sys.argv) == 3 and sys.argv[1] == "rule":
        rule(sys.argv[2])
    elif len(sys.argv) == 4 and sys.argv[1] == "sim":
        sim(sys.argv[2], sys.argv[3])
    elif len(sys.argv) in (7, 8) and sys.argv[1] == "voices":
        voices(*sys.argv[2:7], sys.argv[7] if len(sys.argv) == 8 else None)
    elif len(sys.argv) in (5, 6) and sys.argv[1] == "answers":
        answers(sys.argv[2], sys.argv[3], sys.argv[4], sys.argv[5] if len(sys.argv) == 6 else None)
    else:
        raise SystemExit(__doc__)
