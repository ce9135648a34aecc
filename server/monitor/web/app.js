// The monitor: asks for a token when the farm needs one, then polls the coordinator once a
// second while the tab is visible (docs/monitor.md says why polling). #/ is the farm,
// #/job/ID a job.
import * as api from './api.js';
import * as farmView from './farm_view.js';
import * as jobView from './job_view.js';

const POLL_MS = 1000;
let timer = null;

function route() {
  const m = location.hash.match(/^#\/job\/([0-9A-Za-z_.-]+)$/);
  return m ? { job: m[1] } : { job: null };
}

function show(id) {
  for (const section of ['login', 'farm', 'job']) document.getElementById(section).hidden = section !== id;
}

async function tick() {
  timer = null;
  const status = document.getElementById('status');
  try {
    const { job } = route();
    if (job) {
      await jobView.render(job);
      show('job');
    } else {
      farmView.render(await api.getJson('api/farm'));
      show('farm');
    }
    status.textContent = '';
  } catch (e) {
    if (e instanceof api.Unauthenticated) {
      api.clearToken();
      document.getElementById('login-error').textContent = e.message;
      show('login');
      return;  // polling resumes after a token is given
    }
    status.textContent = e.message.includes('fetch') ? 'coordinator unreachable' : e.message;
  }
  schedule();
}

function schedule(delay = POLL_MS) {
  if (timer !== null) clearTimeout(timer);
  // A hidden tab does not poll: an open but unseen page costs the coordinator nothing.
  if (!document.hidden) timer = setTimeout(tick, delay);
}

async function whoami() {
  try {
    const me = await api.getJson('api/whoami');
    document.getElementById('identity').textContent = me.identity + (me.admin ? ' (admin)' : '');
    return true;
  } catch (e) {
    if (!(e instanceof api.Unauthenticated)) throw e;
    api.clearToken();
    show('login');
    return false;
  }
}

document.getElementById('login').addEventListener('submit', async (event) => {
  event.preventDefault();
  api.setToken(document.getElementById('token').value);
  if (await whoami()) schedule(0);
  else document.getElementById('login-error').textContent = 'invalid client token';
});
document.addEventListener('visibilitychange', () => schedule(0));
window.addEventListener('hashchange', () => schedule(0));
jobView.bind(() => route().job);

if (await whoami()) schedule(0);
