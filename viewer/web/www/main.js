// Starts the viewer: the store of ?store=URL (else the page's sphereclip-store), the view of the
// URL fragment (#camera=LAT,LON,ALT,HEADING,PITCH,FOV&shading=lit|none&atmosphere=on|off&renderer=…),
// on WebGPU if the browser has it, else WebGL2 (?gpu=webgpu or ?gpu=webgl2 asks for one); the
// tiles made by web workers (worker.js; ?workers=N of them, each request given up after
// ?timeout=SECONDS).
import init, { start } from './sc_view_web.js';
import { panel } from './panel.js';

const status = document.getElementById('status');
const query = new URLSearchParams(location.search);
const named = query.get('store')
  ?? document.querySelector('meta[name="sphereclip-store"]').content;
const store = new URL(named, location.href).href.replace(/\/+$/, '');

try {
  await init();
  const number = (name) => (query.has(name) ? Number(query.get(name)) : undefined);
  window.sphereclip = await start(document.getElementById('planet'), store, query.get('gpu'),
    new URL('worker.js', import.meta.url).href, number('workers'), number('timeout'));
  panel(window.sphereclip, document.getElementById('panel'));
} catch (e) {
  const text = String(e?.message ?? e);
  status.textContent = text;
  status.classList.add('error');
  window.sphereclipError = text;
}
// a link edited by hand is a new view
window.addEventListener('hashchange', () => location.reload());
