#!/usr/bin/env bash
# glTF export of the tiny sample's asset (made by e2e_tiny_sample, the fixture): every take and
# the timeline script's result as clips; the Khronos validator finds no error; re-imported with
# tinygltf the mesh and the clips are the asset's; the compressed export (--compress, a JPEG
# texture) passes the validator too, is smaller, and decoded with meshoptimizer's decoder its
# every frame lies within 1 mm of the plain export's; a WebP texture (EXT_texture_webp) passes
# the validator and re-imports; bad input is refused with a clear message.
# usage: gltf_export.sh <tiny session> <work dir>   (FOURD_BIN: folder of the executables)
set -euo pipefail
source "$(dirname "$0")/export_common.sh"

echo "== export"
"$bin/fourd-export" "$asset" -o "$work/tiny.glb" --script "$script"
echo "== Khronos validator"
node "$here/validate_gltf.js" "$work/tiny.glb"
echo "== re-import"
"$bin/gltf_check" "$asset" "$work/tiny.glb" timeline

echo "== compressed"
"$bin/fourd-export" "$asset" -o "$work/tiny_compressed.glb" --script "$script" \
  --compress --texture-format jpeg --texture-size 256
node "$here/validate_gltf.js" "$work/tiny_compressed.glb"
"$bin/glb_decode_check" "$asset" "$work/tiny.glb" "$work/tiny_compressed.glb" 1.0
plain_size=$(stat -c %s "$work/tiny.glb")
packed_size=$(stat -c %s "$work/tiny_compressed.glb")
echo "size: $plain_size bytes plain, $packed_size compressed"
[ $((packed_size * 3)) -lt "$plain_size" ] || { echo "compressed is not 3x smaller"; exit 1; }
echo "== WebP texture (EXT_texture_webp)"
"$bin/fourd-export" "$asset" -o "$work/tiny_webp.glb" --texture-format webp --texture-size 256
node "$here/validate_gltf.js" "$work/tiny_webp.glb"
"$bin/gltf_check" "$asset" "$work/tiny_webp.glb"

echo "== bad input"
head -c 5000 "$asset" > "$work/truncated.fourd"
expect_failure 4 "$work/truncated.fourd" "$bin/fourd-export" "$work/truncated.fourd" -o "$work/t.glb"
test ! -e "$work/t.glb" || { echo "a .glb was written for a corrupt asset"; exit 1; }
expect_failure 2 "--texture-format gif" "$bin/fourd-export" "$asset" -o "$work/t.glb" \
  --texture-format gif
touch "$work/a_file"
expect_failure 5 "$work/a_file" "$bin/fourd-export" "$asset" -o "$work/a_file/out.glb"
echo "gltf export ok"
