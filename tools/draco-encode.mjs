// Writes a Draco-compressed copy of a glTF file with Google's reference encoder
// (draco3dgltf) through glTF-Transform's draco(): the way three.js and Blender-adjacent
// pipelines make KHR_draco_mesh_compression files. Installed by tools/install-draco-encoder.
// Use: node tools/draco-encode.mjs IN.gltf OUT.glb [edgebreaker|sequential]
import { createRequire } from 'node:module';
import { fileURLToPath } from 'node:url';
import path from 'node:path';

const here = path.dirname(fileURLToPath(import.meta.url));
const require = createRequire(path.join(here, '.draco', 'node_modules', 'x.js'));
const { NodeIO } = require('@gltf-transform/core');
const { ALL_EXTENSIONS } = require('@gltf-transform/extensions');
const { draco } = require('@gltf-transform/functions');
const draco3d = require('draco3dgltf');

const [input, output, method] = process.argv.slice(2);
const io = new NodeIO().registerExtensions(ALL_EXTENSIONS).registerDependencies({
  'draco3d.encoder': await draco3d.createEncoderModule(),
  'draco3d.decoder': await draco3d.createDecoderModule(),
});
const document = await io.read(input);
await document.transform(draco({ method: method || 'edgebreaker' }));
await io.write(output, document);
