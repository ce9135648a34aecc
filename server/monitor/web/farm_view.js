// The main page: every job, every worker and every ray server, refreshed by app.js.
import * as fmt from './format.js';

function cell(row, text, className) {
  const td = row.insertCell();
  td.textContent = text;
  if (className) td.className = className;
  return td;
}

export function render(farm) {
  const jobs = document.querySelector('#jobs tbody');
  jobs.replaceChildren();
  for (const job of farm.jobs) {
    const row = jobs.insertRow();
    row.dataset.job = job.id;
    row.dataset.state = job.state;
    row.className = 'clickable';
    row.addEventListener('click', () => { location.hash = '#/job/' + job.id; });
    cell(row, job.id, 'job-id');
    cell(row, job.name, 'job-name');
    cell(row, job.owner || '—', 'job-owner');
    cell(row, job.state, 'job-state state-' + job.state);
    cell(row, String(job.priority), 'job-priority');
    cell(row, fmt.frames(job), 'job-frames');
    const progress = cell(row, '', 'job-progress');
    const bar = document.createElement('progress');
    bar.max = job.tiles_total;
    bar.value = job.tiles_done;
    progress.append(bar, ` ${job.tiles_done}/${job.tiles_total}`);
    cell(row, fmt.seconds(job.eta_seconds), 'job-eta');
    cell(row, fmt.fixed(job.mrays_per_second, 2), 'job-mrays');
    cell(row, fmt.rmse(job.estimated_rmse), 'job-rmse');
  }
  // Finished frames of jobs with a recorded output that no client has delivered yet.
  const d = farm.delivery;
  document.querySelector('#delivery').textContent = d && d.frames > 0
    ? `Undelivered: ${d.frames} finished frames (${(d.bytes / 1e9).toFixed(2)} GB), the oldest finished ` +
      `${fmt.seconds(d.oldest_seconds)} ago; kept until \`tessera collect\` or \`tessera watch\` writes them` +
      (d.limit_bytes > 0 ? ` (new jobs refused at ${(d.limit_bytes / 1e9).toPrecision(3)} GB)` : '')
    : '';
  const workers = document.querySelector('#workers tbody');
  workers.replaceChildren();
  for (const w of farm.workers) {
    const row = workers.insertRow();
    row.dataset.worker = w.name;
    cell(row, w.name, 'worker-name');
    cell(row, String(w.threads), 'worker-threads');
    cell(row, w.embree_isa, 'worker-isa');
    cell(row, w.state, 'worker-state');
    cell(row, fmt.fixed(w.tiles_per_second, 2), 'worker-tiles-per-second');
    cell(row, String(w.tiles_held), 'worker-tiles-held');
    cell(row, String(w.tiles_done), 'worker-tiles-done');
    cell(row, String(w.faults), 'worker-faults').title = w.last_fault;
    cell(row, w.blocklisted_for.join(', ') || '—', 'worker-blocklisted');
  }
  const rays = document.querySelector('#rayservers tbody');
  rays.replaceChildren();
  for (const r of farm.ray_servers) {
    const row = rays.insertRow();
    row.dataset.rayserver = r.id;
    cell(row, r.address, 'rayserver-address');
    cell(row, String(r.threads), 'rayserver-threads');
    cell(row, r.embree_isa, 'rayserver-isa');
    cell(row, r.tls ? 'TLS' : 'plaintext', 'rayserver-security');
    cell(row, String(r.requests), 'rayserver-requests');
    cell(row, String(r.rays), 'rayserver-rays');
    cell(row, String(r.rays_in_flight), 'rayserver-in-flight');
    cell(row, fmt.seconds(r.up_seconds), 'rayserver-up');
  }
}
