"""Independent check of ist_monitor's ROS 2 messages and bags with the `rosbags` package.

    rosbags_interop.py write DIR   write a rosbag2 MCAP folder (zstd chunks) holding one sample
                                   message of every type, little endian, plus the PointCloud2
                                   sample in big endian on /big_endian/cloud
    rosbags_interop.py read BAG    read a bag written by ist_monitor (a .mcap file or a folder)
                                   and print, as JSON, per topic: the type, the message count,
                                   whether the schema text equals rosbags' own definition, and
                                   the first message as rosbags decodes it

The samples here and in tests/messages.rs hold the same values, so the Rust side can check both
the decoded values and the bytes.
"""
import json
import math
import sys
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import Reader, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

TS = get_typestore(Stores.ROS2_JAZZY)
# The Jazzy store has no control_msgs: SpeedScalingFactor is registered from its .msg text as
# control_msgs (ros-controls) defines it, comments and all, so that rosbags parses it itself.
TS.register(get_types_from_msg(
    '# A factor to scale trajectory execution by: 1.0 is normal speed, 0.0 a full pause.\n'
    '# Negative values are not allowed.\n'
    '\n'
    'float64 factor\n',
    'control_msgs/msg/SpeedScalingFactor'))
M = TS.types


def time(sec, nanosec):
    return M['builtin_interfaces/msg/Time'](sec=sec, nanosec=nanosec)


def header(frame):
    return M['std_msgs/msg/Header'](stamp=time(1700000000, 123456789), frame_id=frame)


def vec(x, y, z):
    return M['geometry_msgs/msg/Vector3'](x=x, y=y, z=z)


def quat(x, y, z, w):
    return M['geometry_msgs/msg/Quaternion'](x=x, y=y, z=z, w=w)


def point(x, y, z):
    return M['geometry_msgs/msg/Point'](x=x, y=y, z=z)


def color(r, g, b, a):
    return M['std_msgs/msg/ColorRGBA'](r=r, g=g, b=b, a=a)


def samples():
    field = M['sensor_msgs/msg/PointField']
    fields = [field(name=n, offset=o, datatype=7, count=1) for n, o in (('x', 0), ('y', 4), ('z', 8))]
    cloud = M['sensor_msgs/msg/PointCloud2'](
        header=header('camera_optical_frame'), height=1, width=2, fields=fields,
        is_bigendian=False, point_step=16, row_step=32,
        data=np.frombuffer(np.array([[1.0, 2.0, 3.0, 0.0], [-1.5, 0.25, 4.0, 0.0]],
                                    dtype='<f4').tobytes(), dtype=np.uint8),
        is_dense=True)
    ts = M['geometry_msgs/msg/TransformStamped'](
        header=header('world'), child_frame_id='camera_link',
        transform=M['geometry_msgs/msg/Transform'](translation=vec(1.2, 0.0, 0.8),
                                                   rotation=quat(0.0, 0.247, 0.0, 0.969)))
    empty_image = M['sensor_msgs/msg/CompressedImage'](
        header=M['std_msgs/msg/Header'](stamp=time(0, 0), frame_id=''), format='',
        data=np.zeros(0, dtype=np.uint8))
    marker = M['visualization_msgs/msg/Marker'](
        header=header('world'), ns='closest', id=3, type=5, action=0,
        pose=M['geometry_msgs/msg/Pose'](position=point(0.0, 0.0, 0.0), orientation=quat(0.0, 0.0, 0.0, 1.0)),
        scale=vec(0.01, 0.0, 0.0), color=color(1.0, 0.5, 0.0, 1.0),
        lifetime=M['builtin_interfaces/msg/Duration'](sec=0, nanosec=500000000), frame_locked=False,
        points=[point(0.1, 0.2, 0.3), point(0.4, 0.5, 0.6)], colors=[], texture_resource='',
        texture=empty_image, uv_coordinates=[], text='0.123 m', mesh_resource='',
        mesh_file=M['visualization_msgs/msg/MeshFile'](filename='', data=np.zeros(0, dtype=np.uint8)),
        mesh_use_embedded_materials=False)
    kv = M['diagnostic_msgs/msg/KeyValue']
    status = M['diagnostic_msgs/msg/DiagnosticStatus'](
        level=1, name='ist_monitor: distance', message='warn: 0.2 m', hardware_id='demo_arm',
        values=[kv(key='latency_ms', value='1.5'), kv(key='points', value='307200')])
    return [
        ('/time', 'builtin_interfaces/msg/Time', time(-3, 999999999)),
        ('/header', 'std_msgs/msg/Header', header('base_link')),
        ('/float64', 'std_msgs/msg/Float64', M['std_msgs/msg/Float64'](data=0.0979)),
        ('/bool', 'std_msgs/msg/Bool', M['std_msgs/msg/Bool'](data=True)),
        ('/cloud', 'sensor_msgs/msg/PointCloud2', cloud),
        ('/joint_states', 'sensor_msgs/msg/JointState', M['sensor_msgs/msg/JointState'](
            header=header(''), name=['shoulder_pan', 'elbow'],
            position=np.array([0.5, -1.25]), velocity=np.array([]), effort=np.array([]))),
        ('/image', 'sensor_msgs/msg/Image', M['sensor_msgs/msg/Image'](
            header=header('camera'), height=2, width=3, encoding='16UC1', is_bigendian=0, step=6,
            data=np.arange(12, dtype=np.uint8))),
        ('/camera_info', 'sensor_msgs/msg/CameraInfo', M['sensor_msgs/msg/CameraInfo'](
            header=header('camera'), height=480, width=640, distortion_model='plumb_bob',
            d=np.array([0.1, -0.2, 0.0, 0.0, 0.05]),
            k=np.array([525.0, 0, 319.5, 0, 525.0, 239.5, 0, 0, 1]),
            r=np.array([1.0, 0, 0, 0, 1, 0, 0, 0, 1]),
            p=np.array([525.0, 0, 319.5, 0, 0, 525.0, 239.5, 0, 0, 0, 1, 0]),
            binning_x=0, binning_y=0,
            roi=M['sensor_msgs/msg/RegionOfInterest'](x_offset=1, y_offset=2, height=3, width=4,
                                                      do_rectify=True))),
        ('/tf', 'tf2_msgs/msg/TFMessage', M['tf2_msgs/msg/TFMessage'](transforms=[ts])),
        ('/transform_stamped', 'geometry_msgs/msg/TransformStamped', ts),
        ('/pose', 'geometry_msgs/msg/Pose', M['geometry_msgs/msg/Pose'](
            position=point(1.0, -2.0, 3.0), orientation=quat(0.0, 0.0, 0.6, 0.8))),
        ('/markers', 'visualization_msgs/msg/MarkerArray',
         M['visualization_msgs/msg/MarkerArray'](markers=[marker])),
        ('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray',
         M['diagnostic_msgs/msg/DiagnosticArray'](header=header(''), status=[status])),
        ('/speed_scaling', 'control_msgs/msg/SpeedScalingFactor',
         M['control_msgs/msg/SpeedScalingFactor'](factor=0.35)),
    ]


def write(out):
    writer = Writer(out, version=8, storage_plugin=StoragePlugin.MCAP)
    writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    with writer:
        items = samples()
        items.append(('/big_endian/cloud', 'sensor_msgs/msg/PointCloud2', None))
        for i, (topic, ty, msg) in enumerate(items):
            conn = writer.add_connection(topic, ty, typestore=TS)
            if msg is None:
                big = samples()[4][2]
                big.is_bigendian = True
                big.data = np.frombuffer(np.frombuffer(big.data.tobytes(), dtype='<f4')
                                         .astype('>f4').tobytes(), dtype=np.uint8)
                data = TS.serialize_cdr(big, ty, little_endian=False)
            else:
                data = TS.serialize_cdr(msg, ty)
            writer.write(conn, 1000 + i, data)


def plain(value):
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if hasattr(value, '__dataclass_fields__'):
        return {k: plain(getattr(value, k)) for k in value.__dataclass_fields__ if k != '__msgtype__'}
    if isinstance(value, (np.floating, np.integer)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        # JSON has no infinity: the monitor publishes +inf (nothing hidden) and NaN (failed).
        return str(value)
    return value


def read(path):
    out = {}
    with Reader(Path(path)) as reader:
        for conn, _, raw in reader.messages():
            entry = out.setdefault(conn.topic, {'type': conn.msgtype, 'count': 0})
            entry['count'] += 1
            if entry['count'] == 1:
                own = TS.generate_msgdef(conn.msgtype, ros_version=2)[0]
                entry['definition_matches'] = conn.msgdef.data == own
                entry['first'] = plain(TS.deserialize_cdr(raw, conn.msgtype))
    print(json.dumps(out))


if __name__ == '__main__':
    {'write': write, 'read': read}[sys.argv[1]](sys.argv[2])
