#!/usr/bin/env bash
# Validate glTF / GLB files with the Khronos glTF validator (npm package gltf-validator),
# installed on first use into a project-local folder (.tools/gltf-validator, git-ignored).
#
#   scripts/validate_gltf.sh FILE.glb [FILE.glb ...]
#
# Prints the validator's counts per file and every error and warning; exits 1 when any file
# has an error or a warning (infos and hints are printed, not failed on), 2 when the
# validator cannot be installed (node/npm missing or the registry unreachable).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
tools="$root/.tools/gltf-validator"
version="2.0.0-dev.3.10"
if [ $# -eq 0 ]; then
    echo "usage: $0 FILE.glb [FILE.glb ...]" >&2
    exit 2
fi
if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
    echo "validate_gltf: node and npm are needed (apt-get install nodejs npm)" >&2
    exit 2
fi
if [ ! -f "$tools/node_modules/gltf-validator/package.json" ]; then
    mkdir -p "$tools"
    (cd "$tools" && npm install --no-audit --no-fund --silent --prefix . "gltf-validator@$version" >&2) || {
        echo "validate_gltf: npm install gltf-validator@$version failed" >&2
        exit 2
    }
fi
NODE_PATH="$tools/node_modules" node - "$@" <<'JS'
const fs = require('fs');
const validator = require('gltf-validator');
(async () => {
  let failed = false;
  for (const file of process.argv.slice(2)) {
    const bytes = new Uint8Array(fs.readFileSync(file));
    const report = await validator.validateBytes(bytes, { maxIssues: 100 });
    const i = report.issues;
    console.log(`${file}: ${i.numErrors} errors, ${i.numWarnings} warnings, ${i.numInfos} infos, ${i.numHints} hints` +
      ` (${report.info ? report.info.totalVertexCount : '?'} vertices, ${report.info ? report.info.materialCount : '?'} materials)`);
    for (const m of i.messages) {
      if (m.severity <= 1) console.log(`  ${m.severity === 0 ? 'error' : 'warning'} ${m.code}: ${m.message} ${m.pointer || ''}`);
    }
    if (i.numErrors > 0 || i.numWarnings > 0) failed = true;
  }
  process.exit(failed ? 1 : 0);
})().catch((e) => { console.error(`validate_gltf: ${e.message || e}`); process.exit(2); });
JS
