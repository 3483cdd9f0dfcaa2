// Exports EZ-Tree (npm `@dgreenheck/ez-tree`, MIT, Daniel Greenheck) presets as GLB with
// three.js's own GLTFExporter, as the EZ-Tree web app does, plus the generator's own
// branch hierarchy as CSV, so the analysis can be checked against the truth.
//
//   cd scripts/eztree && npm install && node export.mjs OUT_DIR [PRESET[:SEED] ...]
//   node export.mjs --list    (the preset names)
//
// With no preset, every shipped preset is exported at its own seed. Each preset P gives
// OUT_DIR/P.tree.glb and OUT_DIR/P.branches.csv with the header
// `branch,parent,level,section,x,y,z,radius`: one row per ring of every branch, as the
// generator laid it out (ring centre = section origin; parent empty for the trunk).
//
// Geometry is exported unmodified. Textures are not: outside a browser three.js cannot
// decode or encode images, so the bark and leaf maps are removed before export (the
// importer reads only meshes and base colours).
import { writeFileSync, mkdirSync } from 'node:fs';
import { join } from 'node:path';

// The browser APIs three.js touches when loading textures and writing GLB.
globalThis.document = {
  createElementNS: () => ({ addEventListener() {}, removeEventListener() {}, style: {} }),
};
globalThis.FileReader = class {
  readAsArrayBuffer(blob) {
    blob.arrayBuffer().then((b) => {
      this.result = b;
      this.onloadend?.();
    });
  }
  readAsDataURL(blob) {
    blob.arrayBuffer().then((b) => {
      this.result = `data:${blob.type};base64,${Buffer.from(b).toString('base64')}`;
      this.onloadend?.();
    });
  }
};

const { Tree, TreePreset } = await import('@dgreenheck/ez-tree');
const { GLTFExporter } = await import('three/examples/jsm/exporters/GLTFExporter.js');

/** A Tree that records which branch each branch grew from. */
class RecordingTree extends Tree {
  generate() {
    this.records = [];
    super.generate();
  }

  generateBranch(branch) {
    const id = this.records.length;
    this.records.push({
      parent: branch.recordedParent ?? null,
      level: branch.level,
      sections: branch.sectionCount,
      segments: branch.segmentCount,
      firstVertex: this.branches.verts.length / 3,
    });
    const queued = this.branchQueue.length;
    super.generateBranch(branch);
    for (const child of this.branchQueue.slice(queued)) child.recordedParent = id;
  }
}

function branchesCsv(tree) {
  const v = tree.branches.verts;
  const rows = ['branch,parent,level,section,x,y,z,radius'];
  tree.records.forEach((b, id) => {
    const perRing = b.segments + 1; // the first vertex is repeated for the UV seam
    for (let s = 0; s <= b.sections; s++) {
      const first = b.firstVertex + s * perRing;
      let c = [0, 0, 0];
      for (let j = 0; j < b.segments; j++) {
        for (let k = 0; k < 3; k++) c[k] += v[3 * (first + j) + k] / b.segments;
      }
      const r = Math.hypot(...[0, 1, 2].map((k) => v[3 * first + k] - c[k]));
      rows.push([id, b.parent ?? '', b.level, s, ...c, r].join(','));
    }
  });
  return rows.join('\n') + '\n';
}

async function exportPreset(outDir, name, seed) {
  const tree = new RecordingTree();
  tree.loadPreset(name);
  if (seed !== undefined) {
    tree.options.seed = seed;
    tree.generate();
  }
  for (const mesh of [tree.branchesMesh, tree.leavesMesh]) {
    for (const key of ['map', 'aoMap', 'normalMap', 'roughnessMap']) mesh.material[key] = null;
  }
  const glb = await new GLTFExporter().parseAsync(tree, { binary: true });
  const stem = seed === undefined ? name : `${name}-${seed}`;
  const file = stem.toLowerCase().replace(/[^a-z0-9-]+/g, '_');
  writeFileSync(join(outDir, `${file}.tree.glb`), Buffer.from(glb));
  writeFileSync(join(outDir, `${file}.branches.csv`), branchesCsv(tree));
  const vertices = tree.branches.verts.length / 3;
  const leafVertices = tree.leaves.verts.length / 3;
  console.log(
    `${file}: ${tree.records.length} branches, ${vertices} trunk vertices, ${leafVertices} leaf vertices` +
      (vertices > 65535 || leafVertices > 65535 ? ' (over 65535: EZ-Tree\'s 16-bit indices wrap)' : ''),
  );
}

const [outDir, ...args] = process.argv.slice(2);
if (outDir === '--list') {
  console.log(Object.keys(TreePreset).join('\n'));
  process.exit(0);
}
if (!outDir) {
  console.error('usage: node export.mjs OUT_DIR [PRESET[:SEED] ...]');
  process.exit(2);
}
mkdirSync(outDir, { recursive: true });
const wanted = args.length ? args : Object.keys(TreePreset);
for (const arg of wanted) {
  const [name, seed] = arg.split(':');
  await exportPreset(outDir, name, seed === undefined ? undefined : Number(seed));
}
