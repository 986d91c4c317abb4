// A tile maker: the viewer's wasm in a web worker, making the tiles the page asks for from the
// store over HTTP (synchronous requests: a worker may wait, the page never does). First message
// {store, timeout, record?, filters?}: open the store, answer {record, counts}. Then each {task}:
// answer {made, counts}; each {filters}: the colour filters' new settings. Before each request
// the maker says {asking: URL}. On a failure, answer {failed} and stop (the page starts another).
import init, { TileMaker } from './sc_view_web.js';

let maker = null;
let filters = null;
self.onmessage = async ({ data }) => {
  try {
    if (data.task) {
      const made = maker.make(data.task);
      self.postMessage({ made, counts: maker.counts() }, [made.buffer]);
    } else if (data.store) {
      filters = data.filters ?? filters;
      await init();
      maker = TileMaker.open(data.store, data.timeout, data.record ?? null);
      if (filters) maker.set_filters(filters);
      self.postMessage({ record: maker.record(), counts: maker.counts() });
    } else if (data.filters) {
      // settings that come while the store opens are taken once it is open
      filters = data.filters;
      if (maker) maker.set_filters(filters);
    }
  } catch (e) {
    // a trap leaves the instance unusable
    self.postMessage({ failed: String(e?.message ?? e) });
    self.close();
  }
};
