// Runs the Khronos glTF validator on each .glb file given, printing one JSON line per file:
// {"file": …, "errors": n, "warnings": n, "infos": n, "hints": n, "messages": [{code, severity, pointer, message}]}.
// Needs the npm package gltf-validator on NODE_PATH (.ci/run installs it; see tests/cli_simulate.rs).
const fs = require('fs');
const validator = require('gltf-validator');
(async () => {
  for (const file of process.argv.slice(2)) {
    const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
      uri: file,
      maxIssues: 100,
    });
    const i = report.issues;
    console.log(JSON.stringify({
      file,
      errors: i.numErrors,
      warnings: i.numWarnings,
      infos: i.numInfos,
      hints: i.numHints,
      messages: i.messages.map(m => ({ code: m.code, severity: m.severity, pointer: m.pointer, message: m.message })),
    }));
  }
})().catch(e => {
  console.error(String(e));
  process.exit(1);
});
