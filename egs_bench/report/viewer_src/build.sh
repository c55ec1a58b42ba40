#!/usr/bin/env bash
# Rebuild the report's 3D viewer (../static/viewer.js) from the pinned npm packages in
# package.json / package-lock.json, and copy their licences beside it. Needs node and npm;
# egs-bench itself only ever reads the committed bundle.
set -euo pipefail
cd "$(dirname "$0")"
npm ci --no-audit --no-fund
out=../static
./node_modules/.bin/esbuild src/viewer.js --bundle --format=iife --minify --legal-comments=none \
  --target=es2020 --outfile="$out/viewer.js"
cp node_modules/three/LICENSE "$out/viewer.LICENSE-three.txt"
cp node_modules/@sparkjsdev/spark/LICENSE "$out/viewer.LICENSE-spark.txt"
cp node_modules/fflate/LICENSE "$out/viewer.LICENSE-fflate.txt"  # bundled by Spark
echo "wrote $out/viewer.js ($(wc -c < "$out/viewer.js") bytes)"
