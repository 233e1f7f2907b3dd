#!/usr/bin/env node
// Validates a .glb/.gltf with the Khronos glTF validator (npm package gltf-validator, installed
// globally by scripts/setup.sh): prints the issue counts and every error, warning and info, exits 1
// when there is an error (2 when the validator cannot run).
// usage: node validate_gltf.js FILE
'use strict';
const fs = require('fs');
const path = require('path');
const { execSync } = require('child_process');

function loadValidator() {
  try {
    return require('gltf-validator');
  } catch (e) {
    // A global install is not on node's search path: look where npm puts it.
    const root = execSync('npm root -g').toString().trim();
    return require(path.join(root, 'gltf-validator'));
  }
}

const file = process.argv[2];
if (!file) {
  console.error('usage: node validate_gltf.js FILE');
  process.exit(2);
}
let validator;
try {
  validator = loadValidator();
} catch (e) {
  console.error('gltf-validator is not installed (npm install -g gltf-validator): ' + e.message);
  process.exit(2);
}
const bytes = fs.readFileSync(file);
validator
  .validateBytes(new Uint8Array(bytes), {
    uri: path.basename(file),
    maxIssues: 1000,
    externalResourceFunction: (uri) =>
      new Promise((resolve, reject) => {
        fs.readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)), (err, data) =>
          err ? reject(err.toString()) : resolve(data));
      }),
  })
  .then((report) => {
    const issues = report.issues;
    console.log(`${file}: glTF validator ${report.validatorVersion}: ${issues.numErrors} errors, ` +
                `${issues.numWarnings} warnings, ${issues.numInfos} infos, ${issues.numHints} hints`);
    for (const m of issues.messages) {
      if (m.severity <= 2) {
        const kind = ['error', 'warning', 'info'][m.severity];
        console.log(`  ${kind} ${m.code} at ${m.pointer}: ${m.message}`);
      }
    }
    process.exit(issues.numErrors > 0 ? 1 : 0);
  })
  .catch((error) => {
    console.error(`${file}: the validator could not read it: ${error}`);
    process.exit(1);
  });
