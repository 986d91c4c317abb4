// Starts the viewer: the store of ?store=URL (else the page's sphereclip-store), the view of the
// URL fragment (#camera=LAT,LON,ALT,HEADING,PITCH,FOV&shading=lit|none&atmosphere=on|off&renderer=…).
import init, { start } from './sc_view_web.js';

const status = document.getElementById('status');
const named = new URLSearchParams(location.search).get('store')
  ?? document.querySelector('meta[name="sphereclip-store"]').content;
const store = new URL(named, location.href).href.replace(/\/+$/, '');

try {
  await init();
  window.sphereclip = await start(document.getElementById('planet'), store);
} catch (e) {
  const text = String(e?.message ?? e);
  status.textContent = text;
  status.classList.add('error');
  window.sphereclipError = text;
}
// a link edited by hand is a new view
window.addEventListener('hashchange', () => location.reload());
