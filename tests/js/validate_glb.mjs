// Runs the Khronos glTF-Validator over glb files and prints one JSON line per file:
// {file, numErrors, numWarnings, numInfos, numHints, messages}. Exit 1 if any file has errors,
// 2 if a file could not be read or validated.
//
// MESH_PRIMITIVE_INVALID_ATTRIBUTE is ignored: the validator does not know the namespaced
// KHR_gaussian_splatting:* attributes (KhronosGroup/glTF-Validator#252); splat2tiles checks
// those itself.
import { readFile } from 'node:fs/promises';
import { basename } from 'node:path';
import validator from 'gltf-validator';

const IGNORED = ['MESH_PRIMITIVE_INVALID_ATTRIBUTE'];

const files = process.argv.slice(2);
if (files.length === 0) {
  console.error('usage: node validate_glb.mjs FILE...');
  process.exit(2);
}

let status = 0;
for (const file of files) {
  try {
    const bytes = new Uint8Array(await readFile(file));
    const report = await validator.validateBytes(bytes, {
      uri: basename(file),
      maxIssues: 0,
      ignoredIssues: IGNORED,
      // External resources are never expected in our tiles.
      externalResourceFunction: (uri) => Promise.reject(new Error(`external resource ${uri}`)),
    });
    const issues = report.issues;
    console.log(JSON.stringify({
      file,
      numErrors: issues.numErrors,
      numWarnings: issues.numWarnings,
      numInfos: issues.numInfos,
      numHints: issues.numHints,
      messages: issues.messages,
    }));
    if (issues.numErrors > 0 && status === 0) status = 1;
  } catch (err) {
    console.log(JSON.stringify({ file, failure: String(err && err.message ? err.message : err) }));
    status = 2;
  }
}
// Exit when stdout has drained: process.exit here could cut a piped report.
process.exitCode = status;
