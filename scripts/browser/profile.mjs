// Where the detection worker's time goes: opens the built web studio on the Detect panel with a
// shipped sample, waits for the first detection (the worker ready), then samples the worker's
// JavaScript and wasm with the DevTools protocol's profiler during a second detection of the
// same sample, and prints the functions with the most self time.
//   node scripts/browser/profile.mjs URL [TOP]
// Wasm functions are named only in a build that keeps its name section (scripts/build-web.sh
// --names); scripts/web-profile.sh builds nothing and serves app/dist as it is.
import { launch, openRecorded, waitFor } from "./page.mjs";

const [url, topArg] = process.argv.slice(2);
if (!url) {
  console.error("usage: node profile.mjs URL [TOP]");
  process.exit(2);
}
const top = Number(topArg ?? 30);
const browser = await launch();
let failed = false;
try {
  const { page, lines } = await openRecorded(browser);
  const detections = (l) => l.filter((line) => line.includes("detected "));
  await page.goto(url);
  if (!(await waitFor(page, lines, (l) => detections(l).length >= 1, 120))) {
    throw new Error("the first detection was not logged");
  }
  // The worker is a target of its own: attached through the browser's session, its protocol
  // messages travel inside Target.sendMessageToTarget and come back as events.
  const cdp = await browser.newBrowserCDPSession();
  const { targetInfos } = await cdp.send("Target.getTargets");
  const worker = targetInfos.find((t) => t.type === "worker");
  if (!worker) throw new Error("no worker target");
  const { sessionId } = await cdp.send("Target.attachToTarget", {
    targetId: worker.targetId,
    flatten: false,
  });
  let nextId = 1;
  const pending = new Map();
  cdp.on("Target.receivedMessageFromTarget", (event) => {
    const message = JSON.parse(event.message);
    if (message.id !== undefined && pending.has(message.id)) {
      pending.get(message.id)(message);
      pending.delete(message.id);
    }
  });
  const send = (method, params = {}) =>
    new Promise((done) => {
      const id = nextId++;
      pending.set(id, done);
      cdp.send("Target.sendMessageToTarget", {
        sessionId,
        message: JSON.stringify({ id, method, params }),
      });
    });
  await send("Profiler.enable");
  await send("Profiler.setSamplingInterval", { interval: 100 });
  await send("Profiler.start");
  await page.evaluate(() => {
    location.hash += "~2";
  });
  if (!(await waitFor(page, lines, (l) => detections(l).length >= 2, 120))) {
    throw new Error("the second detection was not logged");
  }
  console.log(detections(lines)[1]);
  const { result } = await send("Profiler.stop");
  const { nodes, samples, timeDeltas } = result.profile;
  const byId = new Map(nodes.map((n) => [n.id, n]));
  const self = new Map();
  let total = 0;
  samples.forEach((id, k) => {
    const dt = timeDeltas[k] ?? 0;
    const name = byId.get(id).callFrame.functionName || "(anonymous)";
    if (name === "(idle)" || name === "(program)") return;
    self.set(name, (self.get(name) ?? 0) + dt);
    total += dt;
  });
  const rows = [...self.entries()].sort((a, b) => b[1] - a[1]).slice(0, top);
  console.log(`worker busy ${(total / 1000).toFixed(1)} ms sampled; self time by function:`);
  for (const [name, us] of rows) {
    const share = ((100 * us) / total).toFixed(1).padStart(5);
    console.log(`${share} %  ${(us / 1000).toFixed(1).padStart(7)} ms  ${name.slice(0, 110)}`);
  }
} catch (e) {
  console.error(String(e));
  failed = true;
} finally {
  await browser.close();
}
process.exit(failed ? 1 : 0);
