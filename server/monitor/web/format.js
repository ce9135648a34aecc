// Number formatting shared by the views.
export function seconds(s) {
  if (s === null || s === undefined) return '—';
  if (s < 60) return s.toFixed(1) + ' s';
  if (s < 3600) return Math.floor(s / 60) + ' min ' + Math.round(s % 60) + ' s';
  return Math.floor(s / 3600) + ' h ' + Math.round((s % 3600) / 60) + ' min';
}
export function fixed(x, digits) { return x === null || x === undefined ? '—' : x.toFixed(digits); }
export function rmse(x) { return x === null || x === undefined ? '—' : x.toPrecision(3); }
export function frames(job) {
  return job.first_frame === job.last_frame ? `${job.first_frame}`
                                            : `${job.first_frame}–${job.last_frame} (${job.frames_done} done)`;
}
// One color per worker index, far apart in hue.
export function workerColor(i) { return `hsl(${(i * 137.508) % 360}, 65%, 55%)`; }
