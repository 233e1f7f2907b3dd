# Sourced by the export tests (gltf_export.sh, mesh_sequence.sh, blender_import.sh,
# threejs_import.sh): their arguments <tiny session> <work dir>, FOURD_BIN, the tiny session's
# asset and timeline script, a fresh work folder, and expect_failure.
session="$1"
work="$2"
bin="${FOURD_BIN:?FOURD_BIN must name the folder of the fourd executables}"
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
asset="$session/asset/motion_graph.fourd"
script="$session/play/timeline.txt"
test -f "$asset" || { echo "no $asset: run the e2e_tiny_sample test first"; exit 1; }
rm -rf "$work"
mkdir -p "$work"

expect_failure() {  # expected exit code, text the message must contain, command...
  local code="$1" text="$2"
  shift 2
  set +e
  out=$("$@" 2>&1)
  status=$?
  set -e
  echo "$out"
  [ "$status" -eq "$code" ] || { echo "exit $status, expected $code"; exit 1; }
  grep -qF -- "$text" <<< "$out" || { echo "the message does not say '$text'"; exit 1; }
}
