#!/usr/bin/env node
// Runs the Khronos glTF Validator on one .glb or .gltf file.
// Usage: node validate.js FILE
// Prints the report's issue counts and messages, then one line
// `RESULT errors=N warnings=N infos=N hints=N` (what tests/gltf_export.rs reads).
// Exit status: 0 when the file has no errors, 1 with errors, 2 when it cannot run.
'use strict';
const fs = require('fs');
const path = require('path');

let validator;
try {
  validator = require('gltf-validator');
} catch (e) {
  console.error('gltf-validator is not installed: run `npm ci --prefix tools/gltf-validator` (' + e.message + ')');
  process.exit(2);
}

const file = process.argv[2];
if (!file) {
  console.error('usage: node validate.js FILE.glb|FILE.gltf');
  process.exit(2);
}
let bytes;
try {
  bytes = fs.readFileSync(file);
} catch (e) {
  console.error('cannot read ' + file + ': ' + e.message);
  process.exit(2);
}

const externalResourceFunction = (uri) =>
  new Promise((resolve, reject) => {
    const p = path.resolve(path.dirname(file), decodeURIComponent(uri));
    fs.readFile(p, (err, data) => (err ? reject(err.toString()) : resolve(new Uint8Array(data))));
  });

validator
  .validateBytes(new Uint8Array(bytes), {
    uri: path.basename(file),
    maxIssues: 0,
    writeTimestamp: false,
    externalResourceFunction,
  })
  .then((report) => {
    const i = report.issues;
    for (const m of i.messages) {
      const severity = ['error', 'warning', 'info', 'hint'][m.severity] || m.severity;
      console.log(`${severity} ${m.code} ${m.pointer || ''}: ${m.message}`);
    }
    const info = report.info || {};
    console.log(`validator ${report.validatorVersion}; ${info.version ? 'glTF ' + info.version : ''} generator ${info.generator || '?'}`);
    console.log(`RESULT errors=${i.numErrors} warnings=${i.numWarnings} infos=${i.numInfos} hints=${i.numHints}`);
    process.exit(i.numErrors === 0 ? 0 : 1);
  })
  .catch((e) => {
    console.error('the validator could not read ' + file + ': ' + e);
    process.exit(2);
  });
