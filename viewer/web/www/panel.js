// The page's panel, as the desktop viewer's: what the view shows (frame rate, the camera, levels,
// tiles, requests, failures) and what a user changes (the camera's mode and speed, the geometry,
// shading, atmosphere, detail, exaggeration, the sun, the colour filters). Every change goes
// through viewer.set(name, value), which applies the window's rules; the controls then show what
// the viewer holds (a rule may have changed more than the one control, or refused it).

const log = (lo, hi, t) => lo * Math.pow(hi / lo, t);
const unlog = (lo, hi, v) => Math.log(v / lo) / Math.log(hi / lo);

export function panel(viewer, root) {
  const facts = document.createElement('div');
  facts.className = 'facts';
  const error = document.createElement('div');
  error.className = 'error';
  root.append(error, facts);
  const controls = [];
  const row = (label, input, parent = root) => {
    const l = document.createElement('label');
    l.append(input, ' ', label);
    parent.append(l);
    return l;
  };
  const set = (name, value) => {
    try {
      viewer.set(name, value);
    } catch (e) {
      console.warn(String(e?.message ?? e));
    }
    refresh();
  };
  const choice = (name, labels, parent = root) => {
    const group = document.createElement('div');
    const inputs = labels.map((text, i) => {
      const r = document.createElement('input');
      r.type = 'radio';
      r.name = name;
      r.addEventListener('change', () => set(name, i));
      row(text, r, group);
      return r;
    });
    parent.append(group);
    controls.push((s) => inputs.forEach((r, i) => { r.checked = s[name] === i; }));
    return inputs;
  };
  const toggle = (name, text, enabled = () => true, parent = root) => {
    const c = document.createElement('input');
    c.type = 'checkbox';
    c.addEventListener('change', () => set(name, c.checked ? 1 : 0));
    row(text, c, parent);
    controls.push((s) => { c.checked = s[name]; c.disabled = !enabled(s); });
  };
  // a slider over [lo, hi], logarithmic when asked; read(s) gives its value
  const slider = (name, text, lo, hi, { logarithmic = false, read = (s) => s[name] } = {},
    parent = root) => {
    const r = document.createElement('input');
    r.type = 'range';
    r.min = 0;
    r.max = 1000;
    const shown = document.createElement('span');
    r.addEventListener('input', () => {
      const t = r.value / 1000;
      set(name, logarithmic ? log(lo, hi, t) : lo + (hi - lo) * t);
    });
    const l = row(text, r, parent);
    l.append(' ', shown);
    controls.push((s) => {
      const v = read(s);
      if (document.activeElement !== r) {
        r.value = 1000 * (logarithmic ? unlog(lo, hi, v) : (v - lo) / (hi - lo));
      }
      shown.textContent = Math.abs(v) >= 10 ? v.toFixed(0) : v.toFixed(2);
    });
  };

  choice('mode', ['orbit (1)', 'fly (2)', 'walk (3)']);
  slider('speed', 'speed', 0.01, 100, { logarithmic: true });
  const geometry = choice('geometry', ['clipmaps', 'CDLOD', 'warp']);
  toggle('level_colors', 'level colours (L)');
  toggle('lit', 'lit (off: colour as stored)');
  toggle('atmosphere', 'atmosphere', (s) => s.lit);
  toggle('detail', 'detail below the data', (s) => s.detail_available);
  slider('exaggeration', 'vertical exaggeration', 0.1, 50, { logarithmic: true });
  slider('sun_azimuth', 'sun azimuth °', 0, 360);
  slider('sun_elevation', 'sun elevation °', -90, 90);
  const first = JSON.parse(viewer.panel());
  first.filters.forEach((f, i) => {
    const box = document.createElement('details');
    const title = document.createElement('summary');
    title.textContent = f.name;
    box.append(title);
    const read = (what) => ({ read: (s) => s.filters[i][what] });
    slider(`filter.${i}.brightness`, 'brightness', -1, 1, read('brightness'), box);
    slider(`filter.${i}.contrast`, 'contrast', 0, 4, read('contrast'), box);
    slider(`filter.${i}.gamma`, 'gamma', 0.1, 10, { logarithmic: true, ...read('gamma') }, box);
    slider(`filter.${i}.saturation`, 'saturation', 0, 4, read('saturation'), box);
    const reset = document.createElement('button');
    reset.textContent = 'reset';
    reset.addEventListener('click', () => set(`filter.${i}.reset`, 1));
    box.append(reset);
    root.append(box);
  });
  const adapter = document.createElement('small');
  root.append(adapter);

  function refresh() {
    const s = JSON.parse(viewer.panel());
    for (const c of controls) c(s);
    geometry[2].disabled = !s.compute;
    geometry[2].title = s.compute ? '' : 'warping needs compute (WebGPU)';
    facts.textContent =
      `${s.fps.toFixed(1)} fps · ${s.cpu_ms.toFixed(1)} ms/frame\n` +
      `${s.lat.toFixed(5)}°, ${s.lon.toFixed(5)}° · ${s.alt.toFixed(1)} m above ground · ` +
      `heading ${s.heading.toFixed(0)}°\n` +
      `levels ${s.level_lo}..${s.level_hi} of ${s.level_wanted} · ${s.tiles} tiles made, ` +
      `cache ${s.cache_mb.toFixed(1)} MiB\n` +
      `${s.requests} requests, ${(s.bytes / 1048576).toFixed(1)} MiB · ${s.makers} workers`;
    error.textContent = s.failed > 0 || s.errors > 0
      ? `${s.failed} failed requests, ${s.errors} tile errors; last: ${s.last_error}` : '';
    adapter.textContent = s.adapter;
  }
  refresh();
  setInterval(() => { if (root.open) refresh(); }, 500);
  root.addEventListener('toggle', refresh);
}
