// Browser tests of the operator-trust fixes: a base64 token (with + / =) connects and the page says
// why it is disconnected; the Control tab acts on the selected drone and asks before fleet-wide
// STOP and LAND ALL; the altitude view shows the wind-turbine climb; the cursor readout.

import assert from 'node:assert/strict';
import { after, before, describe, test } from 'node:test';
import { openBrowser, startKestrel, until } from './harness.mjs';

// What `head -c 16 /dev/urandom | base64` gives: all three characters a URL treats specially.
const BASE64_TOKEN = 'q+/Zk8Lw3rT0uVx/4mN+Aw==';

describe('a base64 token', { timeout: 120_000 }, () => {
  let kestrel;
  let browser;

  before(async () => {
    kestrel = await startKestrel({ drones: 1, speedup: 5, token: BASE64_TOKEN });
    browser = await openBrowser(kestrel.base);
  });

  after(async () => {
    await browser?.close();
    await kestrel?.stop();
  });

  test('with + / = connects: HTTP and the WebSocket (live telemetry)', async () => {
    const { page } = browser;
    await page.locator('#token-dialog[open]').waitFor();
    await browser.login(BASE64_TOKEN);
    await page.locator('.card[data-drone="drone_0"][data-link="ok"]').waitFor({ timeout: 20_000 });
    assert.match(await page.locator('#conn-status').textContent(), /^live/);
  });

  test('the header says kestrel is unreachable when it goes away', async () => {
    const { page } = browser;
    await kestrel.stop();
    await until(page, () => /unreachable/.test(document.querySelector('#conn-status')?.textContent ?? ''), null, 20_000);
    await browser.shot('20-unreachable');
    assert.deepEqual(browser.pageErrors, []);
  });
});

describe('kestrel run with no autopilot connected', { timeout: 120_000 }, () => {
  let kestrel;
  let browser;

  before(async () => {
    kestrel = await startKestrel({ autopilotPort: 14000 + Math.floor(Math.random() * 1000) });
    browser = await openBrowser(kestrel.base);
  });

  after(async () => {
    await browser?.close();
    await kestrel?.stop();
  });

  test('shows no position and no marker, only a drone waiting for its autopilot', async () => {
    const { page } = browser;
    await browser.login();
    await page.locator('.card[data-link="connecting"]').waitFor({ timeout: 20_000 });
    await page.waitForTimeout(1500);
    assert.equal(await page.locator('.card [data-position="none"]').textContent(), 'no position');
    assert.equal(await page.locator('.drone-glyph').count(), 0, 'no made-up marker on the map');
    assert.equal(await page.locator('#alt-view .alt-drone').count(), 0, 'nor in the altitude view');
    assert.match(await page.locator('.card .badge.link').textContent(), /HEARTBEAT/);
    await browser.shot('19-no-autopilot');
  });
});

describe('wind turbine: control of the selected drone, confirmations, altitude view', { timeout: 300_000 }, () => {
  let kestrel;
  let browser;
  let page;

  before(async () => {
    kestrel = await startKestrel({ drones: 2, speedup: 5, scenario: 'missions/scenarios/wind_turbine.json' });
    browser = await openBrowser(kestrel.base);
    page = browser.page;
    await browser.login();
  });

  after(async () => {
    await browser?.close();
    await kestrel?.stop();
  });

  const missionState = (drone) => page.evaluate((d) => document.querySelector(`.mstatus[data-drone="${d}"]`)?.getAttribute('data-state'), drone);

  test('the altitude view shows the climb to the nacelle', async () => {
    await until(page, () => Number(document.querySelector('#alt-view .alt-drone[data-drone="drone_0"]')?.dataset.z) > 20, null, 180_000);
    // The view is redrawn with each telemetry frame: a circle read between two draws has no
    // box, so read it again until it has one.
    const circle = page.locator('#alt-view circle.alt-drone[data-drone="drone_0"]');
    let box = null;
    for (let i = 0; i < 20 && !box; i++) {
      await circle.waitFor({ state: 'visible', timeout: 10_000 });
      box = await circle.boundingBox();
    }
    assert.ok(box, 'the climbing drone has a place in the altitude view');
    const view = await page.locator('#alt-view').boundingBox();
    assert.ok(box.y > view.y && box.y < view.y + view.height / 2, `the climbing drone is in the upper half of the view (${box.y} in ${view.y}..${view.y + view.height})`);
    await browser.shot('21-altitude-view');
  });

  test('the cursor readout gives map coordinates', async () => {
    const map = await page.locator('#map').boundingBox();
    await page.mouse.move(map.x + map.width / 2, map.y + map.height / 2);
    await page.mouse.move(map.x + map.width / 2 + 10, map.y + map.height / 2 + 10);
    assert.match(await page.locator('#cursor-readout').textContent(), /east -?\d+\.\d m, north -?\d+\.\d m/);
  });

  test('Control acts on the selected drone; fleet-wide STOP and LAND ALL ask first', async () => {
    await page.locator('.card[data-drone="drone_1"]').waitFor();
    await page.locator('#drone-select').selectOption({ label: 'drone_0' });
    await page.locator('#tabs [data-tab="control"]').click();
    assert.equal(await page.locator('#ctl-drone').inputValue(), await page.locator('#drone-select').inputValue(), 'Control defaults to the selected drone');
    await page.locator('#drone-select').selectOption({ label: 'drone_1' });
    assert.equal(await page.locator('#ctl-drone option:checked').textContent(), 'drone_1', 'one selection for the whole page');
    await page.locator('#drone-select').selectOption({ label: 'drone_0' });

    await page.locator('#tabs [data-tab="monitor"]').click();
    await until(page, () => document.querySelector('.mstatus[data-drone="drone_0"]')?.getAttribute('data-state') === 'running', null, 20_000);
    await page.locator('#tabs [data-tab="control"]').click();
    await page.locator('#ctl-drone').selectOption({ label: 'all drones' });
    let asked = '';
    page.once('dialog', (d) => {
      asked = d.message();
      return d.dismiss();
    });
    await page.locator('#ctl-buttons [data-action="STOP"]').click();
    await until(page, () => /^rejected: not sent/.test(document.querySelector('#ctl-answer')?.textContent ?? ''), null, 10_000);
    assert.match(asked, /STOP on ALL drones \(drone_0, drone_1\)/);
    await page.waitForTimeout(1000);
    assert.equal(await missionState('drone_0'), 'running', 'a cancelled STOP stops nothing');

    asked = '';
    page.once('dialog', (d) => {
      asked = d.message();
      return d.dismiss();
    });
    await page.locator('#btn-land-all').click();
    await until(page, () => /LAND ALL: rejected/.test(document.querySelector('#toasts')?.textContent ?? ''), null, 10_000);
    assert.match(asked, /LAND ALL/);
    await page.waitForTimeout(1000);
    assert.equal(await missionState('drone_0'), 'running', 'a cancelled LAND ALL lands nothing');
    await browser.shot('22-confirm-cancelled');
    assert.deepEqual(browser.pageErrors, []);
    assert.deepEqual(browser.blocked, []);
  });
});
