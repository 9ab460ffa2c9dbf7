// The new-job form of a process (/?new=1&kind=process): one stock (stored, an STL or a
// block), optional fixture bodies, machine and material, then the operations in order, each
// with its name, program (stored or uploaded), tools (one for every T number, T1..Tn by
// stored tool, a tool library) and simulate or optimize with its limits. Submits the
// document the API takes ({kind: 'process', inputs: {stock, operations: [...]}, options})
// and follows the job's page; a refusal shows the server's problem with its field.
import { el } from './util.js';
import { app, postJson } from './api.js';
import { BUILT_IN_MATERIALS, stored, short, toolLabel, machineLabel, kindSelect, submitJob, showRefusal } from './newjob.js';

const num = (name, value, attrs) => el('input', { name, type: 'number', step: 'any', value, ...(attrs || {}) });
const field = (label, ...input) => el('label', { class: 'field' }, el('span', {}, label), ...input);
const upload = async (collection, file, type) => postJson('/v1/' + collection + '?name=' + encodeURIComponent(file.name), await file.arrayBuffer(), type);
const q = (box, name) => box.querySelector('[name="' + name + '"]');

// A fixture body: a block, a cylinder or an STL (stored as the input `fixture/<name>`).
function fixtureBody(list, n) {
  const block = el('div', { class: 'row', 'data-shape': 'block' }, 'min', num('body_min_x', 0), num('body_min_y', 0), num('body_min_z', -40), 'max', num('body_max_x', 10), num('body_max_y', 10), num('body_max_z', -20));
  const cylinder = el('div', { class: 'row', 'data-shape': 'cylinder', hidden: true }, 'base centre', num('cx', 0), num('cy', 0), num('cz', -40), 'radius', num('radius', 5), 'height', num('height', 20));
  const stl = el('div', { class: 'row', 'data-shape': 'stl', hidden: true }, field('STL file', el('input', { name: 'stl', type: 'file', accept: '.stl' })));
  const shapes = [block, cylinder, stl];
  const kind = el('select', { name: 'body_kind', onchange: () => { for (const s of shapes) s.hidden = s.dataset.shape !== kind.value; } },
    ['block', 'cylinder', 'stl'].map((k) => el('option', { value: k }, k)));
  const box = el('div', { class: 'fixture-body' },
    el('div', { class: 'row' }, field('Body name', el('input', { name: 'body_name', value: 'clamp' + n })), field('Shape', kind),
      el('button', { type: 'button', onclick: () => box.remove() }, 'remove')),
    ...shapes);
  list.append(box);
}

// The bodies as options.fixture takes them, their STLs uploaded into `inputs`.
async function fixtureSpec(list, inputs) {
  const bodies = [];
  for (const box of list.querySelectorAll('.fixture-body')) {
    const name = q(box, 'body_name').value.trim();
    const kind = q(box, 'body_kind').value;
    const v = (k) => +q(box, k).value;
    if (kind === 'block') bodies.push({ name, kind, min: [v('body_min_x'), v('body_min_y'), v('body_min_z')], max: [v('body_max_x'), v('body_max_y'), v('body_max_z')] });
    else if (kind === 'cylinder') bodies.push({ name, kind, base_center: [v('cx'), v('cy'), v('cz')], radius: v('radius'), height: v('height') });
    else {
      const input = 'fixture/' + name;
      const file = q(box, 'stl').files[0];
      if (file) inputs[input] = (await upload('stocks', file, 'application/octet-stream')).id;
      bodies.push({ name, kind, input });
    }
  }
  return bodies.length ? { bodies } : null;
}

// One operation's box: `read()` gives the operation as inputs.operations takes it.
function operationBox(list, n, { tools, libraries, programs }) {
  const toolOptions = () => tools.map((t) => el('option', { value: t.id }, 'stored: ' + toolLabel(t)));
  const numbered = el('div', { class: 'tnumbers' });
  const addNumber = () => {
    const row = el('div', { class: 'row tnumber' }, 'T', num('t_number', numbered.children.length + 1, { step: 1, min: 1, style: 'width: 4em' }),
      el('select', { name: 't_tool' }, toolOptions()), el('button', { type: 'button', onclick: () => row.remove() }, 'remove'));
    numbered.append(row);
  };
  const limits = el('div', { class: 'row limits' },
    field('Max force N', num('max_force', 400)), field('Air feed mm/min', num('air_feed', 5000)), field('Max feed mm/min (optional)', num('max_feed', '')));
  const mode = el('select', { name: 'mode', onchange: () => { limits.hidden = mode.value !== 'optimize'; } },
    el('option', { value: 'optimize' }, 'optimize (limits below)'), el('option', { value: 'simulate' }, 'simulate'));
  const box = el('fieldset', { class: 'operation' },
    el('legend', {}, 'Operation'),
    el('div', { class: 'row' }, field('Name', el('input', { name: 'op_name', value: 'op' + n, maxlength: 100 })),
      el('button', { type: 'button', onclick: () => { box.remove(); renumber(list); } }, 'remove operation')),
    el('div', { class: 'row' },
      field('Program', el('select', { name: 'program_choice' }, el('option', { value: '' }, 'upload (beside)'),
        programs.map((p) => el('option', { value: p.id }, 'stored: ' + (p.name || 'program') + ' · ' + short(p.id))))),
      field('NC program file', el('input', { name: 'program', type: 'file' }))),
    field('Tool for every T number', el('select', { name: 'tool' }, el('option', { value: '' }, 'none (T numbers, library or header below)'), toolOptions())),
    numbered, el('button', { type: 'button', class: 'add-tnumber', onclick: addNumber }, 'add a T number'),
    el('div', { class: 'row' },
      field('Tool library', el('select', { name: 'library' }, el('option', { value: '' }, 'none'),
        libraries.map((l) => el('option', { value: l.id }, (l.name || 'library') + ' · ' + short(l.id))))),
      field('or upload a tool library', el('input', { name: 'library_file', type: 'file' }))),
    field('Run', mode), limits);
  box.read = async () => {
    const op = { name: q(box, 'op_name').value };
    const file = q(box, 'program').files[0];
    if (file) op.program = (await upload('programs', file, 'text/plain')).id;
    else if (q(box, 'program_choice').value) op.program = q(box, 'program_choice').value;
    if (q(box, 'tool').value) op.tool = q(box, 'tool').value;
    for (const row of numbered.querySelectorAll('.tnumber')) op['T' + q(row, 't_number').value] = q(row, 't_tool').value;
    const lib = q(box, 'library_file').files[0];
    if (lib) op.tool_library = (await upload('tool-libraries', lib, 'application/octet-stream')).id;
    else if (q(box, 'library').value) op.tool_library = q(box, 'library').value;
    op.options = {};
    if (mode.value === 'optimize') {
      op.options.limits = {};
      for (const k of ['max_force', 'air_feed', 'max_feed']) if (q(limits, k).value !== '') op.options.limits[k] = +q(limits, k).value;
    }
    return op;
  };
  list.append(box);
  renumber(list);
}

// Each operation's legend says its place in the order.
function renumber(list) {
  [...list.children].forEach((box, i) => { box.dataset.operation = String(i + 1); box.querySelector('legend').textContent = 'Operation ' + (i + 1); });
}

export async function renderProcessForm(route) {
  const [tools, libraries, materials, machines, stocks, programs] = await Promise.all(['tools', 'tool-libraries', 'materials', 'machines', 'stocks', 'programs'].map(stored));
  const out = el('div', { id: 'form-result' });
  const fixtures = el('div', { id: 'fixture-bodies' });
  const operations = el('div', { id: 'operations-form' });
  const addOperation = () => operationBox(operations, operations.children.length + 1, { tools, libraries, programs });
  const form = el('form', { id: 'new-job', class: 'newjob' },
    el('fieldset', {}, el('legend', {}, 'Job'), field('Kind', kindSelect('process', route))),
    el('fieldset', {}, el('legend', {}, 'Stock (one for every operation)'),
      field('Stock', el('select', { name: 'stock_choice' }, el('option', { value: '' }, 'a block (below) or the STL beside'),
        stocks.map((s) => el('option', { value: s.id }, 'stored: ' + (s.name || (s.summary && s.summary.format) || 'stock') + ' · ' + short(s.id))))),
      field('STL file (optional)', el('input', { name: 'stock_stl', type: 'file', accept: '.stl' })),
      el('div', { class: 'muted' }, 'or a block, min and max corners in mm:'),
      el('div', { class: 'row' }, 'min', num('min_x', 0), num('min_y', 0), num('min_z', -20), 'max', num('max_x', 100), num('max_y', 80), num('max_z', 0))),
    el('fieldset', {}, el('legend', {}, 'Fixture (optional: one setup for every operation)'), fixtures,
      el('button', { type: 'button', id: 'add-fixture-body', onclick: () => fixtureBody(fixtures, fixtures.children.length + 1) }, 'add a fixture body')),
    el('fieldset', {}, el('legend', {}, 'Material and machine'),
      field('Material', el('select', { name: 'material' }, BUILT_IN_MATERIALS.map((m) => el('option', { value: 'builtin:' + m }, m)),
        materials.map((m) => el('option', { value: m.id }, 'stored: ' + (m.name || (m.summary && m.summary.name) || 'material') + ' · ' + short(m.id))))),
      field('Machine', el('select', { name: 'machine_choice' }, el('option', { value: '' }, 'generic 3-axis (or the file beside)'),
        machines.map((m) => el('option', { value: m.id }, 'stored: ' + machineLabel(m))))),
      field('Machine JSON (optional)', el('input', { name: 'machine', type: 'file', accept: '.json' })),
      field('Cell mm (optional: else the finest tool\'s default)', num('cell_mm', '')),
      el('label', { class: 'check' }, el('input', { name: 'keep_stocks', type: 'checkbox' }), 'keep the stock after each operation')),
    el('h2', {}, 'Operations, in order'), operations,
    el('button', { type: 'button', id: 'add-operation', onclick: addOperation }, 'add an operation'), ' ',
    el('button', { type: 'submit' }, 'Submit'), ' ', el('a', { href: '/' }, 'back to the list'), out);
  addOperation();
  form.addEventListener('submit', async (e) => {
    e.preventDefault();
    const f = form.elements;
    out.replaceChildren(el('p', { class: 'muted' }, 'uploading…'));
    try {
      const inputs = {};
      const stl = f.stock_stl.files[0];
      if (stl) inputs.stock = (await upload('stocks', stl, 'application/octet-stream')).id;
      else if (f.stock_choice.value) inputs.stock = f.stock_choice.value;
      else inputs.stock = (await postJson('/v1/stocks', { kind: 'block', min: [+f.min_x.value, +f.min_y.value, +f.min_z.value], max: [+f.max_x.value, +f.max_y.value, +f.max_z.value] })).id;
      const options = {};
      if (f.material.value.startsWith('builtin:')) options.material = f.material.value.slice(8);
      else inputs.material = f.material.value;
      const mfile = f.machine.files[0];
      if (mfile) inputs.machine = (await upload('machines', mfile, 'application/json')).id;
      else if (f.machine_choice.value) inputs.machine = f.machine_choice.value;
      if (f.cell_mm.value !== '') options.cell_mm = +f.cell_mm.value;
      if (f.keep_stocks.checked) options.keep_stocks = true;
      const fixture = await fixtureSpec(fixtures, inputs);
      if (fixture) options.fixture = fixture;
      inputs.operations = [];
      for (const box of operations.children) inputs.operations.push(await box.read());
      await submitJob({ kind: 'process', inputs, options }, route);
    } catch (err) {
      showRefusal(err, out);
    }
  });
  app.replaceChildren(el('div', {}, el('a', { href: '/' }, '← all jobs')), el('h1', {}, 'New process'), form);
}
