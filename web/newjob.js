// The new-job form (/?new=1): a program, a stock (STL or block) and a design part, tools (a new one, a stored
// one, or a tool library, stored or uploaded), material and machine (built-in, stored or
// uploaded), limits; submits simulate or optimize and then follows the job's page. A process
// (/?new=1&kind=process: operations in order on one stock) has its own form, processform.js.
import { el, problemView } from './util.js';
import { app, getJson, postJson, handleError } from './api.js';

export const BUILT_IN_MATERIALS = ['Al7075-T6', 'Al6082-T6', 'TC6'];

// Up to 100 stored resources of a collection, newest first (the form lists them to pick).
export async function stored(collection) {
  try { return (await getJson('/v1/' + collection + '?limit=100')).items; } catch (_) { return []; }
}
export const short = (id) => id.slice(0, 8);

// The kind of job; choosing a process (or leaving it) shows the other form.
export function kindSelect(current, route) {
  const kinds = [['optimize', 'optimize (simulate, then schedule the feeds)'], ['simulate', 'simulate'], ['process', 'process (operations in order on one stock)']];
  const select = el('select', {
    name: 'kind',
    onchange: () => {
      if ((select.value === 'process') === (current === 'process')) return;
      history.pushState(null, '', '/?new=1&kind=' + select.value);
      route();
    },
  }, kinds.map(([k, label]) => el('option', { value: k, selected: k === current }, label)));
  return select;
}

// What the upload's validation found (shape, diameter, flutes; a machine's name and axes).
/** Posts a job and follows it to its page. */
export async function submitJob(body, route) {
  const job = await postJson('/v1/jobs', body);
  history.pushState(null, '', '/jobs/' + job.id);
  route();
}

/** Shows why a submission failed: the server's problem document, naming the field, or the error. */
export function showRefusal(err, out) {
  out.replaceChildren();
  if (err.problem) out.append(el('h2', {}, 'The server refused it'), problemView(err.problem));
  else handleError(err, out);
}

export function toolLabel(r) {
  const d = r.summary || {};
  return (r.name ? r.name + ' · ' : '') + (d.shape || 'tool') + (d.diameter ? ' Ø' + d.diameter : '') + (d.flutes ? ' ' + d.flutes + ' flutes' : '') + ' · ' + short(r.id);
}
export function machineLabel(r) {
  const d = r.summary || {};
  return (r.name || d.name || 'machine') + (d.kinematics ? ' (' + d.kinematics + ')' : '') + ' · ' + short(r.id);
}

export async function renderNewJob(route) {
  const kind = new URLSearchParams(location.search).get('kind');
  if (kind === 'process') {
    (await import('/ui/processform.js')).renderProcessForm(route);
    return;
  }
  const [tools, libraries, materials, machines] = await Promise.all(['tools', 'tool-libraries', 'materials', 'machines'].map(stored));
  const num = (name, value, attrs) => el('input', { name, type: 'number', step: 'any', value, ...(attrs || {}) });
  const field = (label, ...input) => el('label', { class: 'field' }, el('span', {}, label), ...input);
  const out = el('div', { id: 'form-result' });
  const newTool = el('div', { id: 'new-tool' },
    field('Type', el('select', { name: 'tool_type' }, ['flat', 'ball', 'bull', 'chamfer', 'drill'].map((t) => el('option', { value: t }, t)))),
    field('Diameter mm', num('diameter_mm', 10)), field('Corner radius mm (bull)', num('corner_radius_mm', 1)),
    field('Flutes', num('flutes', 4, { step: 1 })), field('Helix °', num('helix_deg', 30)), field('Flute length mm', num('flute_length_mm', 25)));
  const toolSelect = el('select', { name: 'tool_choice', onchange: () => { newTool.hidden = toolSelect.value !== 'new'; } },
    el('option', { value: 'new' }, 'a new tool (below)'),
    tools.map((t) => el('option', { value: t.id }, 'stored: ' + toolLabel(t))),
    el('option', { value: 'none' }, 'none: the tool library gives every T number'));
  const form = el('form', { id: 'new-job', class: 'newjob' },
    el('fieldset', {}, el('legend', {}, 'Job'),
      field('Kind', kindSelect(kind === 'simulate' ? 'simulate' : 'optimize', route)),
      field('NC program', el('input', { name: 'program', type: 'file', required: true }))),
    el('fieldset', {}, el('legend', {}, 'Stock'),
      field('STL file (optional)', el('input', { name: 'stock_stl', type: 'file', accept: '.stl' })),
      el('div', { class: 'muted' }, 'or a block, min and max corners in mm:'),
      el('div', { class: 'row' }, 'min', num('min_x', 0), num('min_y', 0), num('min_z', -20), 'max', num('max_x', 100), num('max_y', 80), num('max_z', 0)),
      field('Design part STL (optional: gouges and the allowance left, in the stock\'s frame)', el('input', { name: 'part_stl', type: 'file', accept: '.stl' }))),
    el('fieldset', {}, el('legend', {}, 'Tools'),
      field('Tool for every T number', toolSelect), newTool,
      el('div', { class: 'row' },
        field('Tool library (T numbers the tool above does not give)', el('select', { name: 'library' }, el('option', { value: '' }, 'none'),
          libraries.map((l) => el('option', { value: l.id }, (l.name || 'library') + ' · ' + short(l.id))))),
        field('or upload a tool library', el('input', { name: 'library_file', type: 'file' })))),
    el('fieldset', {}, el('legend', {}, 'Material and machine'),
      field('Material', el('select', { name: 'material' }, BUILT_IN_MATERIALS.map((m) => el('option', { value: 'builtin:' + m }, m)),
        materials.map((m) => el('option', { value: m.id }, 'stored: ' + (m.name || (m.summary && m.summary.name) || 'material') + ' · ' + short(m.id))))),
      field('Machine', el('select', { name: 'machine_choice' }, el('option', { value: '' }, 'generic 3-axis (or the file beside)'),
        machines.map((m) => el('option', { value: m.id }, 'stored: ' + machineLabel(m))))),
      field('Machine JSON (optional)', el('input', { name: 'machine', type: 'file', accept: '.json' }))),
    el('fieldset', {}, el('legend', {}, 'Limits (optimize)'),
      field('Max force N', num('max_force', 400)), field('Air feed mm/min', num('air_feed', 5000)), field('Max feed mm/min (optional)', num('max_feed', ''))),
    el('button', { type: 'submit' }, 'Submit'), ' ', el('a', { href: '/' }, 'back to the list'), out);
  form.addEventListener('submit', async (e) => {
    e.preventDefault();
    const f = form.elements;
    out.replaceChildren(el('p', { class: 'muted' }, 'uploading…'));
    const upload = async (collection, file, type) => postJson('/v1/' + collection + '?name=' + encodeURIComponent(file.name), await file.arrayBuffer(), type);
    try {
      const inputs = {};
      inputs.program = (await upload('programs', f.program.files[0], 'text/plain')).id;
      const stl = f.stock_stl.files[0];
      inputs.stock = (stl ? await upload('stocks', stl, 'application/octet-stream')
        : await postJson('/v1/stocks', { kind: 'block', min: [+f.min_x.value, +f.min_y.value, +f.min_z.value], max: [+f.max_x.value, +f.max_y.value, +f.max_z.value] })).id;
      const part = f.part_stl.files[0];
      if (part) inputs.part = (await upload('stocks', part, 'application/octet-stream')).id;
      if (f.tool_choice.value === 'new') {
        const t = { type: f.tool_type.value, diameter_mm: +f.diameter_mm.value, flutes: +f.flutes.value, helix_deg: +f.helix_deg.value, flute_length_mm: +f.flute_length_mm.value };
        if (t.type === 'bull') t.corner_radius_mm = +f.corner_radius_mm.value;
        inputs.tool = (await postJson('/v1/tools', t)).id;
      } else if (f.tool_choice.value !== 'none') inputs.tool = f.tool_choice.value;
      const lib = f.library_file.files[0];
      if (lib) inputs.tool_library = (await upload('tool-libraries', lib, 'application/octet-stream')).id;
      else if (f.library.value) inputs.tool_library = f.library.value;
      const options = {};
      if (f.material.value.startsWith('builtin:')) options.material = f.material.value.slice(8);
      else inputs.material = f.material.value;
      const mfile = f.machine.files[0];
      if (mfile) inputs.machine = (await upload('machines', mfile, 'application/json')).id;
      else if (f.machine_choice.value) inputs.machine = f.machine_choice.value;
      if (f.kind.value === 'optimize') {
        options.limits = {};
        for (const k of ['max_force', 'air_feed', 'max_feed']) if (f[k].value !== '') options.limits[k] = +f[k].value;
      }
      await submitJob({ kind: f.kind.value, inputs, options }, route);
    } catch (err) {
      showRefusal(err, out);
    }
  });
  app.replaceChildren(el('div', {}, el('a', { href: '/' }, '← all jobs')), el('h1', {}, 'New job'), form);
}
