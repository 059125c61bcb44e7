// Runs the Khronos glTF validator (npm package `gltf-validator`) on .glb files and exits
// non-zero when any has an error. Install it outside the repository and point NODE_PATH at it:
//   npm install --prefix /tmp/gltf-validator gltf-validator
//   NODE_PATH=/tmp/gltf-validator/node_modules node tests/gltf/validate.cjs take.glb [more.glb]
// `cargo test --test gltf` runs it too when GLTF_VALIDATOR_MODULES names that node_modules.
const fs = require('fs');
const validator = require('gltf-validator');

async function main(files) {
  if (files.length === 0) {
    console.error('usage: node tests/gltf/validate.cjs FILE.glb [...]');
    process.exit(2);
  }
  let failed = false;
  for (const file of files) {
    const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)));
    const { numErrors, numWarnings, numInfos } = report.issues;
    console.log(`${file}: ${numErrors} errors, ${numWarnings} warnings, ${numInfos} infos (gltf-validator ${report.validatorVersion})`);
    for (const m of report.issues.messages) {
      if (m.severity <= 1) console.log(`  ${m.severity === 0 ? 'error' : 'warning'} ${m.code} at ${m.pointer}: ${m.message}`);
    }
    failed ||= numErrors > 0;
  }
  process.exit(failed ? 1 : 0);
}

main(process.argv.slice(2));
