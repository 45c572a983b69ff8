// Browser test of a Kestrel its fleet refused (issue 26, item 1): node_1's credentials file has
// the wrong password, so node_0 refuses it. node_1's ground station shows a banner saying it has
// not joined, naming node_0's address and why, and the server refuses a mission meanwhile;
// the unit tests (web/test/remote.test.ts) check that it goes once joined.

import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { after, before, describe, test } from 'node:test';
import { fleetOf, freePort, freeUdpPort, openBrowser, startKestrel } from './harness.mjs';

describe('a Kestrel its fleet refused', { timeout: 60_000 }, () => {
  const fleet = `join-${process.pid}`;
  const identities = fleetOf(2, fleet);
  const dir = identities.dir;
  const nodes = [];
  let busPorts;
  let browser;

  before(async () => {
    const creds = ['farm:right-secret', 'farm:wrong-secret'].map((line, i) => {
      const file = path.join(dir, `creds-${i}`);
      fs.writeFileSync(file, `${line}\n`);
      return file;
    });
    busPorts = [await freePort(), await freePort()];
    for (const id of [0, 1]) {
      const udpPort = await freeUdpPort();
      nodes.push(await startKestrel({ config: identities.config(id, busPorts, { udpPort, credentials: creds[id] }) }));
    }
    browser = await openBrowser(nodes[1].base, { width: 1024, height: 768 });
  });

  after(async () => {
    await browser?.close();
    for (const n of nodes) await n?.stop();
    identities.remove();
  });

  test('its ground station shows a banner naming the peer that refused it and why', async () => {
    const { page } = browser;
    await browser.login();
    const banner = page.locator('#fleet-join-banner');
    await banner.waitFor({ state: 'visible', timeout: 15_000 });
    await page.waitForFunction(
      () => /refused this node/.test(document.querySelector('#fleet-join-banner')?.textContent ?? ''),
      null,
      { timeout: 15_000 },
    );
    const text = await banner.textContent();
    assert.match(text, new RegExp(`^Not joined to fleet ${fleet} \\(node node_1\\): waiting for 127\\.0\\.0\\.1:${busPorts[0]} \\(refused this node: credentials do not match\\)\\.`));
    assert.match(text, /Missions and explorations are refused until it joins/);
    assert.equal(await banner.getAttribute('role'), 'alert');
    assert.match(await page.locator('#fleet-bus').textContent(), /refused joins [1-9]/);
    await browser.shot('fleet-join-10-refused-banner');

    const mission = { target: 'drone_1', plan: [{ behavior: 'takeoff', args: { height: 2 } }] };
    const answer = await nodes[1].api('POST', '/api/mission_update', { drone_id: 'drone_1', mission_id: 1, item_id: null, action: 0, mission });
    assert.equal(answer.status, 409, JSON.stringify(answer.json));
    assert.equal(answer.json.code, 'fleet_not_joined');
    assert.match(answer.json.reason, new RegExp(`waiting for 127\\.0\\.0\\.1:${busPorts[0]} \\(refused this node`));
    assert.deepEqual(browser.pageErrors, []);
    assert.deepEqual(browser.blocked, []);
  });
});
