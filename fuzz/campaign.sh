#!/usr/bin/env bash
# Runs every fuzz target for RUNS executions (default 10 million) or MAX_S seconds (default one
# hour), whichever comes first, one after the other, and prints libFuzzer's final statistics.
#   bash fuzz/campaign.sh [target ...]         (from the checkout; nightly and cargo-fuzz needed)
# Corpora grow under $CORPUS (default /tmp/ist_monitor-fuzz/corpus), seeded from fuzz/seeds and
# from the project's own files (the configs, the demo URDF, its meshes with a format byte);
# a finding is written under $CORPUS/../artifacts/<target>/ and stops that target.
set -euo pipefail
cd "$(dirname "$0")/.."
RUNS=${RUNS:-10000000}
MAX_S=${MAX_S:-3600}
CORPUS=${CORPUS:-/tmp/ist_monitor-fuzz/corpus}
ART=$(dirname "$CORPUS")/artifacts
targets=("$@")
[[ ${#targets[@]} -gt 0 ]] || targets=(pointcloud2 messages pcd ply mesh params mcap urdf)
cargo +nightly fuzz build -s none -O
bin=fuzz/target/x86_64-unknown-linux-gnu/release
for t in "${targets[@]}"; do
  mkdir -p "$CORPUS/$t" "$ART/$t"
  cp -n fuzz/seeds/"$t"/* "$CORPUS/$t/" 2>/dev/null || true
  case $t in
    params) cp -n config/*.yaml "$CORPUS/$t/" ;;
    urdf) cp -n urdf/*.urdf "$CORPUS/$t/" ;;
    mesh) for m in urdf/meshes/*.stl; do (printf '\0'; cat "$m") > "$CORPUS/$t/$(basename "$m")"; done
          for m in tests/meshes/*.dae; do (printf '\2'; cat "$m") > "$CORPUS/$t/$(basename "$m")"; done ;;
  esac
  echo "== $t"
  "$bin/$t" "$CORPUS/$t" -runs="$RUNS" -max_total_time="$MAX_S" -max_len=65536 \
    -rss_limit_mb=2048 -timeout=10 -print_final_stats=1 -artifact_prefix="$ART/$t/" 2>&1 |
    grep -E "^(#[0-9]+[[:space:]]+DONE|stat::|==[0-9]+== ERROR|SUMMARY|fuzz:|thread .* panicked)" || true
done
