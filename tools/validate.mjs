// Validates glTF files with the Khronos glTF validator installed by tools/install-validator.
//
//   node tools/validate.mjs FILE...
//
// Prints `FILE: N errors, N warnings, N infos` per file, then one line per message
// (severity, code, JSON pointer, text). External resources (the .bin of a .gltf) are read
// relative to the file. Exits 1 if any file has an error or a warning or cannot be read,
// 2 if the validator is not installed, 0 otherwise.

import { createRequire } from "node:module";
import { existsSync } from "node:fs";
import { readFile } from "node:fs/promises";
import path from "node:path";
import { fileURLToPath } from "node:url";

const toolsDir = path.dirname(fileURLToPath(import.meta.url));
const validatorDir = path.join(toolsDir, ".validator", "node_modules", "gltf-validator");
const SEVERITIES = ["error", "warning", "info", "hint"];

function loadValidator() {
  if (!existsSync(validatorDir)) {
    console.error(`validate.mjs: gltf-validator not installed (run: bash tools/install-validator)`);
    process.exit(2);
  }
  const require = createRequire(import.meta.url);
  return require(validatorDir);
}

async function validateFile(validator, file) {
  const data = new Uint8Array(await readFile(file));
  const directory = path.dirname(path.resolve(file));
  const report = await validator.validateBytes(data, {
    uri: path.basename(file),
    maxIssues: 0,
    externalResourceFunction: async (uri) =>
      new Uint8Array(await readFile(path.resolve(directory, decodeURIComponent(uri)))),
  });
  const issues = report.issues;
  console.log(
    `${file}: ${issues.numErrors} errors, ${issues.numWarnings} warnings, ${issues.numInfos} infos`,
  );
  for (const message of issues.messages) {
    const severity = SEVERITIES[message.severity] ?? String(message.severity);
    const pointer = message.pointer ?? "";
    console.log(`  ${severity} ${message.code} ${pointer}: ${message.message}`);
  }
  return issues.numErrors === 0 && issues.numWarnings === 0;
}

async function main() {
  const files = process.argv.slice(2);
  if (files.length === 0) {
    console.error("usage: node tools/validate.mjs FILE...");
    process.exit(2);
  }
  const validator = loadValidator();
  let clean = true;
  for (const file of files) {
    try {
      clean = (await validateFile(validator, file)) && clean;
    } catch (error) {
      console.log(`${file}: cannot validate: ${error}`);
      clean = false;
    }
  }
  process.exit(clean ? 0 : 1);
}

await main();
