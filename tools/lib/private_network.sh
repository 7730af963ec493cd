# Sourced by the tools that open DDS or zenoh sessions (they discover by multicast or scouting):
# `require_private_network NAME` exits unless this process is in a network namespace whose only
# interface is loopback (../shared/tools/netns-run).
require_private_network() {
  local interfaces
  interfaces=$(awk -F: 'NR > 2 { gsub(/ /, "", $1); print $1 }' /proc/self/net/dev | sort | xargs)
  if [ "$interfaces" != lo ]; then
    echo "$1: network interfaces [$interfaces]: run it inside ../shared/tools/netns-run" >&2
    exit 2
  fi
}
