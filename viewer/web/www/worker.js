// A tile maker: the viewer's wasm in a web worker, making the tiles the page asks for from the
// store over HTTP (synchronous requests with a timeout: a worker may wait, the page never does).
// First message {store, timeout, record?}: open the store, answer {record, counts}. Then each
// {task}: answer {made, counts}. On a failure, answer {failed} and stop (the page starts another).
import init, { TileMaker } from './sc_view_web.js';

let maker = null;
self.onmessage = async ({ data }) => {
  try {
    if (data.task) {
      const made = maker.make(data.task);
      self.postMessage({ made, counts: maker.counts() }, [made.buffer]);
    } else {
      await init();
      maker = TileMaker.open(data.store, data.timeout, data.record ?? null);
      self.postMessage({ record: maker.record(), counts: maker.counts() });
    }
  } catch (e) {
    // a trap leaves the instance unusable
    self.postMessage({ failed: String(e?.message ?? e) });
    self.close();
  }
};
