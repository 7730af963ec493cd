#!/usr/bin/env bash
# The cost of securing the cell: the real Kinect cloud (9.8 MB PointCloud2 of
# ../shared/bags/moveit_perception_tutorial) published at --rate Hz by an independent camera into
# the node (release build, the Panda config, the cloud on /camera/depth/points as the cell's
# policies name it), its answers on ~/distance recorded by `ist_monitor record` (received less the
# cloud's stamp), the node's CPU over the publishing from /proc. The modes, alternated --rounds
# times in one run:
#   dds          Debian's Cyclone DDS 0.10 in C (tests/peers/cyclone_secure_peer.c --cdr), unsecured
#   dds-messages-only  the same, the node with writers_from_discovery:=false (the cost of asking
#                discovery for the source's writers on every frame)
#   dds-sros2    the same, all three secured: SROS2 enclaves of config/security/cell_policy.xml
#                (/cell/camera, /cell/ist_monitor, /cell/operator), Enforce, metadata ENCRYPT, data NONE
#   zenoh        rmw_zenoh's default: peers that `ist_monitor zenoh-router` introduces, tcp; the camera
#                is the eclipse-zenoh Python peer (tools/camera_peer.py --transport zenoh)
#   zenoh-mtls   the secured cell of docs/security.md: clients of the router
#                (config/zenoh/secure_router.json5: mTLS, access control) over quic/, a certificate each
#   zenoh-tls    the same over tls/ (zenoh 1.10's TLS link crashes under this load: docs/security.md)
# One line per run: delivered of sent, latency p50 / p99 / max, the node's CPU (cores); a process
# that died is named.
#
#   ../shared/tools/netns-run tools/security_latency.sh [--rounds 3] [--seconds 10] [--rate 30]
#                                                       [--modes dds,dds-sros2,zenoh,zenoh-mtls]
#
# Needs: target/release/ist_monitor (cargo build --release), .venv with rosbags and eclipse-zenoh
# (.ci/run makes it), Cyclone's idlc, headers and security plugins, gcc, openssl. DDS discovers by
# multicast: it refuses to run outside a private network namespace that has only loopback.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$PWD
rounds=3 seconds=10 rate=30 modes=dds,dds-sros2,zenoh,zenoh-mtls
while [ $# -gt 0 ]; do
  case "$1" in
    --rounds) rounds=$2; shift 2 ;;
    --seconds) seconds=$2; shift 2 ;;
    --rate) rate=$2; shift 2 ;;
    --modes) modes=$2; shift 2 ;;
    *) echo "security_latency.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
source tools/lib/private_network.sh
require_private_network security_latency.sh
bin=$repo/target/release/ist_monitor
bag=$repo/../shared/bags/moveit_perception_tutorial/perception_tutorial_mcap
config=$repo/config/panda_perception_tutorial.yaml
for need in "$bin" .venv/bin/python "$bag"; do
  [ -e "$need" ] || { echo "security_latency.sh: $need is missing" >&2; exit 2; }
done
work=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null || true; rm -rf "$work"' EXIT

# The Cyclone peer, the Kinect frame as the bag holds it, the SROS2 keystore, the zenoh certificates.
idlc -o "$work" tests/peers/ros_msgs.idl >/dev/null 2>&1
gcc -O2 -Wall -Werror -o "$work/peer" tests/peers/cyclone_secure_peer.c "$work/ros_msgs.c" \
  -I "$work" -lddsc -lm
.venv/bin/python - "$bag" "$work/kinect.cdr" <<'EOF'
import sys
from pathlib import Path
from rosbags.highlevel import AnyReader
with AnyReader([Path(sys.argv[1])]) as r:
    clouds = [c for c in r.connections if c.msgtype == "sensor_msgs/msg/PointCloud2"]
    _, _, raw = next(r.messages(connections=clouds))
    Path(sys.argv[2]).write_bytes(raw)
EOF
ks="$work/ks"
python3 tools/sros2_keystore.py create_keystore --metadata-protection ENCRYPT \
  --data-protection NONE "$ks" >/dev/null
python3 tools/sros2_keystore.py generate_artifacts "$ks" config/security/cell_policy.xml \
  /cell/camera /cell/ist_monitor /cell/operator >/dev/null
tools/zenoh_certs.sh "$work/certs" router ist_monitor camera robot hmi >/dev/null 2>&1

cpu_ticks() { awk '{ print $14 + $15 }' "/proc/$1/stat" 2>/dev/null || echo 0; }
tls() { # the member's certificate and key, as ZENOH_CONFIG_OVERRIDE entries
  echo "transport/link/tls/connect_certificate=\"certs/$1.pem\";transport/link/tls/connect_private_key=\"certs/$1.key\""
}

run() { # $1: a mode
  local mode=$1 env_node=() env_rec=() node_args=() camera=() router="" link=""
  case "$mode" in
    dds) ;;
    dds-messages-only) node_args=(-p writers_from_discovery:=false) ;;
    dds-sros2)
      env_node=(ROS_SECURITY_ENABLE=true ROS_SECURITY_STRATEGY=Enforce ROS_SECURITY_KEYSTORE="$ks")
      env_rec=("${env_node[@]}" ROS_SECURITY_ENCLAVE_OVERRIDE=/cell/operator)
      node_args=(--enclave /cell/ist_monitor)
      ;;
    zenoh)
      env_node=(RMW_IMPLEMENTATION=rmw_zenoh_cpp)
      env_rec=("${env_node[@]}")
      ;;
    zenoh-mtls | zenoh-tls)
      link=quic
      [ "$mode" = zenoh-tls ] && link=tls
      router="listen/endpoints=[\"$link/localhost:7447\"]"
      env_node=(RMW_IMPLEMENTATION=rmw_zenoh_cpp
        ZENOH_SESSION_CONFIG_URI="$repo/config/zenoh/secure_session.json5"
        ZENOH_CONFIG_OVERRIDE="connect/endpoints=[\"$link/localhost:7447\"]")
      env_rec=(RMW_IMPLEMENTATION=rmw_zenoh_cpp
        ZENOH_SESSION_CONFIG_URI="$repo/config/zenoh/secure_session.json5"
        ZENOH_CONFIG_OVERRIDE="connect/endpoints=[\"$link/localhost:7447\"];$(tls hmi)")
      ;;
    *) echo "security_latency.sh: unknown mode $mode" >&2; exit 2 ;;
  esac
  cd "$work"
  local router_pid=""
  if [[ $mode == zenoh* ]]; then
    if [ -n "$router" ]; then
      env ZENOH_ROUTER_CONFIG_URI="$repo/config/zenoh/secure_router.json5" \
        ZENOH_CONFIG_OVERRIDE="$router" "$bin" zenoh-router >"$work/router.log" 2>&1 &
    else
      "$bin" zenoh-router >"$work/router.log" 2>&1 &
    fi
    router_pid=$!
    sleep 2
  fi
  env "${env_node[@]}" "$bin" node --config "$config" \
    --ros-args -p kinect.topic:=/camera/depth/points "${node_args[@]}" 2>"$work/node.log" &
  local node=$!
  for _ in $(seq 1200); do grep -q 'up:' "$work/node.log" && break; sleep 0.1; done
  grep -q 'up:' "$work/node.log" || { echo "$mode: the node did not come up:" >&2; tail -5 "$work/node.log" >&2; exit 1; }
  env "${env_rec[@]}" "$bin" record --out "$work/r.mcap" --duration $((seconds + 5)) \
    >"$work/record.txt" 2>"$work/record.log" &
  local record=$!
  sleep 2
  local t0 c0 sent
  t0=$(date +%s.%N) c0=$(cpu_ticks $node)
  case "$mode" in
    dds | dds-messages-only | dds-sros2)
      [ "$mode" = dds-sros2 ] && camera=(--enclave "$ks/enclaves/cell/camera")
      "$work/peer" "${camera[@]}" --cdr "$work/kinect.cdr" --rate "$rate" --no-float \
        --timeout "$seconds" >"$work/camera.json" 2>"$work/camera.log" || true
      sent=$(python3 -c 'import json,sys; print(json.load(sys.stdin)["clouds_sent"])' \
        <"$work/camera.json" 2>/dev/null || echo "?")
      ;;
    *)
      local zc=(--connect tcp/localhost:7447)
      [ -n "$router" ] && zc=(--zenoh-config "$repo/config/zenoh/secure_session.json5"
        --zenoh-override "connect/endpoints=[\"$link/localhost:7447\"];$(tls camera)")
      "$repo/.venv/bin/python" "$repo/tools/camera_peer.py" "$bag" --mode cloud --transport zenoh \
        --topic /camera/depth/points --rate "$rate" --duration "$seconds" --wait 0 "${zc[@]}" \
        >"$work/camera.json" 2>"$work/camera.log" || true
      sent=$(python3 -c 'import json,sys; print(json.loads(sys.stdin.read().splitlines()[-1])["published"])' \
        <"$work/camera.json" 2>/dev/null || echo "?")
      ;;
  esac
  local t1 c1
  t1=$(date +%s.%N) c1=$(cpu_ticks $node)
  local died=()
  wait $record || died+=(record)
  kill -0 $node 2>/dev/null || died+=(node)
  if [ -n "$router_pid" ]; then kill -0 "$router_pid" 2>/dev/null || died+=(router); fi
  kill $node $router_pid 2>/dev/null || true
  wait $node $router_pid 2>/dev/null || true
  rm -rf "$work/r.mcap"
  cd "$repo"
  local line cores
  line=$(grep '^~/distance' "$work/record.txt" || echo "~/distance: 0 frames")
  cores=$(python3 -c "print(f'{($c1 - $c0) / $(getconf CLK_TCK) / ($t1 - $t0):.2f}')")
  echo "$mode: sent $sent, $line, node CPU $cores cores${died:+, died: ${died[*]}}"
}

echo "Kinect cloud $(stat -c %s "$work/kinect.cdr") B at $rate Hz for $seconds s, $(nproc) cores, $(date -u +%FT%TZ)"
for r in $(seq "$rounds"); do
  for m in ${modes//,/ }; do run "$m"; done
done
