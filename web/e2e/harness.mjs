// E2E harness: starts a real `kestrel sim` (or `kestrel run` with a config) on a free loopback
// port, opens the ground station it
// serves in Debian's chromium (playwright-core, never a downloaded browser), blocks and records
// every request that is not to the loopback interface, and saves screenshots as artifacts.

import { execFileSync, spawn } from 'node:child_process';
import dgram from 'node:dgram';
import fs from 'node:fs';
import net from 'node:net';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { chromium } from 'playwright-core';

const HERE = path.dirname(fileURLToPath(import.meta.url));
export const ARTIFACTS = process.env.ARTIFACTS_DIR ?? path.resolve(HERE, '../../artifacts/web');
const CHROMIUM = process.env.CHROMIUM_BIN ?? '/usr/bin/chromium';
export const TOKEN = 'e2e-token-7f3a';

const CHROMIUM_ARGS = [
  '--no-sandbox',
  '--disable-gpu',
  '--disable-quic',
  '--no-first-run',
  '--disable-background-networking',
  '--disable-component-update',
  '--disable-sync',
  '--disable-dev-shm-usage',
];

const LOCAL_HOSTS = new Set(['127.0.0.1', 'localhost', '[::1]', '::1']);

// Ports are drawn below the kernel's ephemeral range (32768-60999 on Linux), so that no
// outgoing connection (Chromium's, a Kestrel's bus link) can take one between the check here and
// the Kestrel binding it: a port from `listen(0)` is an ephemeral one, and once it raced that way.
const PORT_LOW = 20000;
const PORT_HIGH = 32767;

function randomPort() {
  return PORT_LOW + Math.floor(Math.random() * (PORT_HIGH - PORT_LOW + 1));
}

function tryTcp(port) {
  return new Promise((resolve) => {
    const srv = net.createServer();
    srv.unref();
    srv.once('error', () => resolve(false));
    srv.listen(port, '127.0.0.1', () => srv.close(() => resolve(true)));
  });
}

function tryUdp(port) {
  return new Promise((resolve) => {
    const sock = dgram.createSocket('udp4');
    sock.once('error', () => {
      sock.close();
      resolve(false);
    });
    sock.bind(port, '127.0.0.1', () => sock.close(() => resolve(true)));
  });
}

async function freeOf(tryPort) {
  for (let attempt = 0; attempt < 200; attempt++) {
    const port = randomPort();
    if (await tryPort(port)) return port;
  }
  throw new Error(`no free port in ${PORT_LOW}-${PORT_HIGH} after 200 tries`);
}

export function freePort() {
  return freeOf(tryTcp);
}

export function freeUdpPort() {
  return freeOf(tryUdp);
}

/**
 * A fleet of `nodes` Kestrels on one bus: each node's signing key (`kestrel fleet-key`) in a
 * temporary folder, and `config(id, busPorts, { udpPort, credentials })`, node `node_{id}`'s
 * config (its drone `drone_{id}` on a UDP port where no autopilot answers, its bus port, the
 * earlier nodes to connect to, its key and the roster). `remove()` deletes the folder.
 */
export function fleetOf(nodes, fleet) {
  const bin = path.resolve(process.env.KESTREL_BIN ?? '');
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'kestrel-e2e-fleet-'));
  const roster = [];
  for (let id = 0; id < nodes; id++) {
    const out = execFileSync(bin, ['fleet-key', path.join(dir, `node_${id}.key`)], { encoding: 'utf8' });
    const key = /public key: (\S+)/.exec(out)?.[1];
    if (!key) throw new Error(`kestrel fleet-key printed no public key: ${out}`);
    roster.push('', `[fleet.roster.node_${id}]`, `keys = ["${key}"]`, `drones = ["drone_${id}"]`);
  }
  const config = (id, busPorts, { udpPort, credentials = null }) => {
    const connect = busPorts.slice(0, id).map((p) => `tcp/127.0.0.1:${p}`);
    return [
      '[[vehicle]]',
      `id = "drone_${id}"`,
      `connection = "udpin:127.0.0.1:${udpPort}"`,
      '',
      '[fleet]',
      'enabled = true',
      `name = "${fleet}"`,
      `node = "node_${id}"`,
      `listen = ["tcp/127.0.0.1:${busPorts[id]}"]`,
      `connect = ${JSON.stringify(connect)}`,
      ...(credentials ? [`credentials_file = "${credentials}"`] : []),
      `key_file = "${path.join(dir, `node_${id}.key`)}"`,
      ...roster,
      '',
    ].join('\n');
  };
  return { dir, config, remove: () => fs.rmSync(dir, { recursive: true, force: true }) };
}

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

/**
 * Starts `kestrel sim --no-demo` (or `--scenario FILE`, which flies its mission; or with `demo`,
 * the sim's demo mission on every drone) and waits for its health route; returns a handle. With `autopilotPort`, `kestrel run` instead, waiting for an
 * autopilot there. With `config` (TOML text), `kestrel run --config` with it.
 */
export async function startKestrel({ drones = 2, speedup = 5, token = TOKEN, scenario = null, demo = false, autopilotPort = null, config = null } = {}) {
  if (!process.env.KESTREL_BIN) throw new Error('KESTREL_BIN must name the kestrel binary to test');
  const bin = path.resolve(process.env.KESTREL_BIN);
  const port = await freePort();
  const base = `http://127.0.0.1:${port}`;
  const logPath = path.join(ARTIFACTS, `kestrel-${port}.log`);
  fs.mkdirSync(ARTIFACTS, { recursive: true });
  const log = fs.openSync(logPath, 'w');
  const flightLog = path.join(ARTIFACTS, `flight-${port}.jsonl`);
  const args = ['sim', '--no-demo', '--drones', String(drones), '--speedup', String(speedup), '--listen', `127.0.0.1:${port}`, '--log', flightLog];
  // `kestrel run` waiting for an autopilot at a UDP port where nothing answers.
  if (autopilotPort) args.splice(0, 6, 'run', '--platform', 'px4', '--connection', `udpin:127.0.0.1:${autopilotPort}`);
  if (scenario) args.splice(args.indexOf('--no-demo'), 1, '--scenario', path.resolve(HERE, '../..', scenario));
  else if (demo) args.splice(args.indexOf('--no-demo'), 1);
  // A scratch working directory: nothing kestrel writes lands in the repository.
  const cwd = fs.mkdtempSync(path.join(os.tmpdir(), 'kestrel-e2e-run-'));
  if (config !== null) {
    fs.writeFileSync(path.join(cwd, 'kestrel.toml'), config);
    args.splice(0, 6, 'run', '--config', path.join(cwd, 'kestrel.toml'));
  }
  const child = spawn(bin, args, {
    cwd,
    env: { ...process.env, KESTREL_API_TOKEN: token },
    stdio: ['ignore', log, log],
  });
  let exited = null;
  child.on('exit', (code, signal) => (exited = { code, signal }));
  const deadline = Date.now() + 60_000;
  for (;;) {
    if (exited) throw new Error(`kestrel exited early (${JSON.stringify(exited)}); see ${logPath}:\n${fs.readFileSync(logPath, 'utf8').slice(-2000)}`);
    try {
      const res = await fetch(`${base}/api/health`);
      if (res.ok) break;
    } catch {
      // not listening yet
    }
    if (Date.now() > deadline) {
      child.kill('SIGKILL');
      throw new Error(`kestrel did not answer /api/health within 60 s; see ${logPath}`);
    }
    await sleep(200);
  }
  const page = await fetch(`${base}/`).then((r) => r.text());
  if (!page.includes('Kestrel ground station')) {
    child.kill('SIGKILL');
    throw new Error(`kestrel at ${bin} does not serve the ground station at /: build web/dist before kestrel`);
  }
  return {
    base,
    port,
    logPath,
    flightLog,
    async api(method, route, body) {
      const res = await fetch(`${base}${route}`, {
        method,
        headers: { Authorization: `Bearer ${token}`, 'Content-Type': 'application/json' },
        body: body === undefined ? undefined : JSON.stringify(body),
      });
      const text = await res.text();
      return { status: res.status, json: text ? JSON.parse(text) : null };
    },
    /** Kills it at once (SIGKILL): a Kestrel that dies, not one that shuts down. */
    async kill() {
      if (!exited) child.kill('SIGKILL');
      for (let i = 0; i < 50 && !exited; i++) await sleep(100);
    },
    async stop() {
      if (!exited) {
        child.kill('SIGTERM');
        for (let i = 0; i < 50 && !exited; i++) await sleep(100);
        if (!exited) child.kill('SIGKILL');
      }
      fs.rmSync(cwd, { recursive: true, force: true });
    },
  };
}

/** Opens the page in chromium with a fresh profile; every non-loopback request is aborted and kept. */
export async function openBrowser(base, { width = 1400, height = 900 } = {}) {
  if (!fs.existsSync(CHROMIUM)) throw new Error(`${CHROMIUM} missing: apt-get install -y chromium`);
  const profile = fs.mkdtempSync(path.join(os.tmpdir(), 'kestrel-e2e-'));
  const context = await chromium.launchPersistentContext(profile, {
    executablePath: CHROMIUM,
    headless: true,
    args: CHROMIUM_ARGS,
    viewport: { width, height },
  });
  const blocked = [];
  const pageErrors = [];
  await context.route('**/*', (route) => {
    const url = new URL(route.request().url());
    if (url.protocol === 'data:' || url.protocol === 'blob:' || LOCAL_HOSTS.has(url.hostname)) return route.continue();
    blocked.push(url.href);
    return route.abort('blockedbyclient');
  });
  const page = context.pages()[0] ?? (await context.newPage());
  page.on('pageerror', (e) => pageErrors.push(e.message));
  page.on('websocket', (ws) => {
    const url = new URL(ws.url());
    if (!LOCAL_HOSTS.has(url.hostname)) blocked.push(ws.url());
  });
  await page.goto(`${base}/`);
  return {
    page,
    blocked,
    pageErrors,
    async login(token = TOKEN) {
      await page.locator('#token-input').fill(token);
      await page.locator('#token-ok').click();
      await page.locator('#conn-status.ok').waitFor({ timeout: 20_000 });
    },
    async shot(name) {
      fs.mkdirSync(ARTIFACTS, { recursive: true });
      await page.screenshot({ path: path.join(ARTIFACTS, `${name}.png`) });
    },
    async close() {
      await context.close();
      fs.rmSync(profile, { recursive: true, force: true });
    },
  };
}

/** Clicks the map at a point given in ENU metres (through the page's own Leaflet map). */
export async function clickMapAt(page, x, y) {
  const pt = await page.evaluate(([x, y]) => window.__kestrel.mapPoint(x, y), [x, y]);
  await page.mouse.click(pt.x, pt.y);
}

/** Waits for a page condition, polling; returns its last value. */
export async function until(page, fn, arg, timeout = 60_000) {
  const handle = await page.waitForFunction(fn, arg, { timeout, polling: 200 });
  return handle.jsonValue();
}
