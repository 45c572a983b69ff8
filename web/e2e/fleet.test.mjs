// Browser test of the ground station over a fleet bus: two real `kestrel run` processes joined by
// a bus on localhost (no autopilot: each drone stays on the ground and is announced anyway). The
// GS of node_0 shows node_1's drone marked remote with its node, offers no command for it, shows
// the bus line, and shows the drone silent within seconds of node_1 being killed.

import assert from 'node:assert/strict';
import { after, before, describe, test } from 'node:test';
import { fleetOf, freePort, freeUdpPort, openBrowser, startKestrel, until } from './harness.mjs';

describe('two Kestrels on one fleet bus', { timeout: 180_000 }, () => {
  const fleet = `gs-${process.pid}`;
  let nodes = [];
  let browser;

  let identities;

  before(async () => {
    identities = fleetOf(2, fleet);
    const busPorts = [await freePort(), await freePort()];
    for (const id of [0, 1]) {
      nodes.push(await startKestrel({ config: identities.config(id, busPorts, { udpPort: await freeUdpPort() }) }));
    }
    browser = await openBrowser(nodes[0].base, { width: 1024, height: 768 });
  });

  after(async () => {
    await browser?.close();
    for (const n of nodes) await n?.stop();
    identities?.remove();
  });

  test("node_1's drone is listed remote with its node, and not drawn before it has a position", async () => {
    const { page } = browser;
    await browser.login();
    // No autopilot: node_1 announces its drone without a position (null, nothing made up).
    const card = page.locator('.card.remote[data-remote-drone="drone_1"]');
    await card.waitFor({ timeout: 30_000 });
    assert.equal(await card.locator('[data-field="node"]').textContent(), 'remote (node_1)');
    assert.equal(await card.getAttribute('data-link'), 'live');
    assert.equal(await card.locator('[data-field="position"]').textContent(), 'no position yet');
    assert.equal(await page.locator('.drone-glyph.remote[data-remote-drone="drone_1"]').count(), 0);
    // Our own drone is never listed as remote, and node_1's never as ours.
    assert.equal(await page.locator('.drone-glyph.remote[data-remote-drone="drone_0"]').count(), 0);
    assert.equal(await page.locator('.card[data-drone="drone_1"]').count(), 0);
    await browser.shot('fleet-10-remote-drone');
  });

  test('the fleet bus line names the fleet, this node, the peer heard, latency and refusals', async () => {
    const { page } = browser;
    const line = await until(
      page,
      () => {
        const t = document.querySelector('#fleet-bus')?.textContent ?? '';
        return /peers heard 1/.test(t) && /p50 \d/.test(t) ? t : false;
      },
      null,
      20_000,
    );
    assert.match(line, new RegExp(`fleet ${fleet} · node node_0 · peers heard 1 \\(node_1\\)`));
    assert.match(line, /latency p50 [\d.]+ ms \/ p99 [\d.]+ ms · refused \d+/);
  });

  test('no command control is offered for the remote drone', async () => {
    const { page } = browser;
    const card = page.locator('.card.remote[data-remote-drone="drone_1"]');
    assert.equal(await card.locator('button').count(), 0, 'a remote card has no Hold/Land');
    assert.match(await card.locator('[data-field="commands"]').getAttribute('title'), /flown by node_1: use that Kestrel's ground station/);
    // Listed in the header's drone choice, but not choosable.
    const option = page.locator('#drone-select option', { hasText: 'drone_1' });
    assert.equal(await option.count(), 1);
    assert.equal(await option.evaluate((o) => o.disabled), true);
    assert.match(await option.getAttribute('title'), /flown by node_1/);
    // Not a target anywhere else: plan, control and exploration list node_0's drone only.
    for (const sel of ['#panel-plan select', '#panel-control select']) {
      const labels = await page.locator(`${sel} option`).allTextContents();
      assert.ok(!labels.some((l) => l.includes('drone_1')), `${sel} offers drone_1: ${labels}`);
    }
    assert.equal(await page.locator('#panel-explore input[data-drone="drone_1"]').count(), 0);
    // The server refuses a command naming it anyway, with the reason the page shows (app.send).
    const answer = await nodes[0].api('POST', '/api/mission_update', { drone_id: 'drone_1', mission_id: null, item_id: null, action: 5, mission: null });
    assert.equal(answer.status, 409, JSON.stringify(answer.json));
    assert.equal(answer.json.accepted, false);
    assert.equal(answer.json.code, 'remote_drone');
    assert.match(answer.json.reason, /flown by the Kestrel `node_1`/);
  });

  test('killing node_1 shows its drone silent within a few seconds, never as live', async () => {
    const { page } = browser;
    await nodes[1].kill();
    const killedAt = Date.now();
    const card = page.locator('.card.remote[data-remote-drone="drone_1"]');
    await until(page, () => document.querySelector('.card.remote[data-remote-drone="drone_1"]')?.dataset.link === 'silent', null, 8_000);
    const silentAfterMs = Date.now() - killedAt;
    assert.ok(silentAfterMs < 8_000, `silent after ${silentAfterMs} ms`);
    assert.match(await card.locator('[data-field="link"]').textContent(), /^SILENT \d+ S/);
    assert.match(await page.locator('#conn-status').textContent(), /1 remote \(1 silent\)/);
    await browser.shot('fleet-20-remote-silent');
    assert.deepEqual(browser.pageErrors, []);
    assert.deepEqual(browser.blocked, []);
  });
});
