// A job's page: facts, actions, the frame as it converges (a PNG tone-mapped by the
// coordinator, fetched again whenever more tiles arrived), the tile map and the frames.
import * as api from './api.js';
import * as fmt from './format.js';

let shown = { job: null, frame: null, tiles: -1 };
let previewUrl = null;

function fact(list, name, value) {
  const dt = document.createElement('dt');
  dt.textContent = name;
  const dd = document.createElement('dd');
  dd.textContent = value;
  dd.dataset.fact = name;
  list.append(dt, dd);
}

async function refreshPreview(job) {
  const p = job.preview;
  if (!p || (shown.job === job.id && shown.frame === p.frame && shown.tiles === p.tiles_done)) return;
  const blob = await api.getBlob(`api/jobs/${job.id}/preview.png?frame=${p.frame}`);
  const img = document.getElementById('preview');
  const old = previewUrl;
  previewUrl = URL.createObjectURL(blob);
  await new Promise((resolve) => { img.onload = resolve; img.onerror = resolve; img.src = previewUrl; });
  if (old) URL.revokeObjectURL(old);
  shown = { job: job.id, frame: p.frame, tiles: p.tiles_done };
  // What the image shows, for people and for tests: the frame and how many tiles it holds.
  img.dataset.job = job.id;
  img.dataset.frame = p.frame;
  img.dataset.tiles = p.tiles_done;
  document.getElementById('preview-caption').textContent =
    `frame ${p.frame}: ${p.tiles_done} of ${p.tiles_x * p.tiles_y} tiles`;
}

function drawTileMap(job) {
  const p = job.preview;
  const canvas = document.getElementById('tile-map');
  const legend = document.getElementById('tile-legend');
  if (!p) return;
  const scale = Math.max(1, Math.floor(256 / Math.max(p.tiles_x, p.tiles_y)));
  canvas.width = p.tiles_x * scale;
  canvas.height = p.tiles_y * scale;
  const g = canvas.getContext('2d');
  g.fillStyle = '#000';
  g.fillRect(0, 0, canvas.width, canvas.height);
  p.tile_workers.forEach((w, i) => {
    if (w < 0) return;
    g.fillStyle = fmt.workerColor(w);
    g.fillRect((i % p.tiles_x) * scale, Math.floor(i / p.tiles_x) * scale, scale - (scale > 3 ? 1 : 0),
               scale - (scale > 3 ? 1 : 0));
  });
  legend.replaceChildren();
  p.workers.forEach((name, i) => {
    const swatch = document.createElement('span');
    swatch.className = 'legend';
    swatch.style.background = fmt.workerColor(i);
    legend.append(swatch, name);
  });
  canvas.dataset.workers = p.workers.join(',');
}

export async function render(id) {
  const job = await api.getJson(`api/jobs/${id}`);
  document.getElementById('job-title').textContent = `${job.name || '(unnamed)'} · ${job.id}`;
  const facts = document.getElementById('job-facts');
  facts.replaceChildren();
  fact(facts, 'state', job.state);
  fact(facts, 'owner', job.owner || '—');
  fact(facts, 'priority', String(job.priority));
  fact(facts, 'frames', fmt.frames(job));
  fact(facts, 'image', `${job.width}×${job.height}, ${job.spp} spp, tiles of ${job.tile_size} px`);
  fact(facts, 'tiles', `${job.tiles_done} of ${job.tiles_total} (${job.tiles_leased} being rendered)`);
  fact(facts, 'elapsed', fmt.seconds(job.elapsed_seconds));
  fact(facts, 'ETA', fmt.seconds(job.eta_seconds));
  fact(facts, 'Mrays/s', fmt.fixed(job.mrays_per_second, 2));
  fact(facts, 'est. RMSE', fmt.rmse(job.estimated_rmse));
  if (job.output) {
    fact(facts, 'output', `${job.output} (${job.frames_acknowledged} of ${job.frames_done} finished frames delivered)`);
  }
  if (job.error) fact(facts, 'error', job.error);
  const priority = document.getElementById('priority');
  if (document.activeElement !== priority) priority.value = job.priority;
  document.getElementById('cancel').disabled = !['queued', 'running'].includes(job.state);
  const frames = document.querySelector('#frames tbody');
  frames.replaceChildren();
  for (const f of job.frames) {
    const row = frames.insertRow();
    row.dataset.frame = f.frame;
    for (const text of [String(f.frame), `${f.tiles}/${job.tiles_per_frame}`, fmt.fixed(f.wall_seconds, 2),
                        fmt.fixed(f.tile_seconds, 2), fmt.rmse(f.estimated_rmse)]) {
      row.insertCell().textContent = text;
    }
  }
  drawTileMap(job);
  await refreshPreview(job);
}

export function bind(currentJob) {
  const result = document.getElementById('action-result');
  const act = async (what, body) => {
    result.textContent = '';
    result.className = '';
    try {
      await api.postJson(`api/jobs/${currentJob()}/${what}`, body);
      result.textContent = what === 'cancel' ? 'cancelled' : 'priority set';
    } catch (e) {
      result.textContent = e.message;
      result.className = 'error';
    }
  };
  document.getElementById('cancel').addEventListener('click', () => {
    if (confirm(`Cancel job ${currentJob()}?`)) act('cancel', {});
  });
  document.getElementById('set-priority').addEventListener('click', () => {
    act('priority', { priority: Number.parseInt(document.getElementById('priority').value, 10) });
  });
}
