// millsim dashboard: the job list (/), one job (/jobs/{id}) and the new-job form (/?new=1),
// read through the public API under /v1 on this same origin. No build step: ES modules,
// uPlot and three.js vendored with their licences.
import { renderKeyState, whenKeySet } from './api.js';
import { renderList, stopList } from './list.js';
import { renderJob, stopJob } from './job.js';
import { renderNewJob } from './newjob.js';

function route() {
  stopList();
  stopJob();
  renderKeyState();
  const m = location.pathname.match(/^\/jobs\/([^/]+)$/);
  if (m) renderJob(decodeURIComponent(m[1]));
  else if (new URLSearchParams(location.search).get('new')) renderNewJob(route);
  else renderList(route);
}
whenKeySet(route);
window.addEventListener('popstate', route);
route();
