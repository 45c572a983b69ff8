// Browser test of issue 26, item 4: after a page reload the Explore tab shows, from the server's
// state, every drone of a 3-drone exploration and stops the whole run with one action (before,
// only the selected drone was ticked after a reload and Stop stopped one drone of three).

import assert from 'node:assert/strict';
import { after, before, describe, test } from 'node:test';
import { openBrowser, startKestrel, until } from './harness.mjs';

const DRONES = ['drone_0', 'drone_1', 'drone_2'];

describe('exploration survives a page reload', { timeout: 300_000 }, () => {
  let kestrel;
  let browser;
  let page;

  before(async () => {
    kestrel = await startKestrel({ drones: 3, speedup: 5 });
    browser = await openBrowser(kestrel.base);
    page = browser.page;
  });

  after(async () => {
    await browser?.close();
    await kestrel?.stop();
  });

  /** Each drone's phase in the server's run (`GET /api/exploration`), not the page's. */
  const serverPhases = async () => {
    const r = await kestrel.api('GET', '/api/exploration');
    assert.equal(r.status, 200, JSON.stringify(r.json));
    return Object.fromEntries((r.json.progress?.drones ?? []).map((d) => [d.drone, d.phase]));
  };

  test('three drones explore; after a reload all three are shown exploring and one action stops all three', async () => {
    await browser.login();
    await page.locator('#tabs [data-tab="explore"]').click();
    await until(page, (n) => document.querySelectorAll('#exp-drones input[type=checkbox]').length === n, DRONES.length, 20_000);
    assert.equal(await page.locator('#btn-exp-stop-all').isDisabled(), true, 'nothing to stop before a run');
    for (const d of DRONES) await page.locator(`#exp-drones input[data-drone="${d}"]`).check();
    await page.locator('#btn-exp-start').click();
    await until(page, () => /^accepted: exploring: /.test(document.querySelector('#exp-answer')?.textContent ?? ''), null, 20_000);
    await until(page, (n) => document.querySelectorAll('#exp-table tr.exploring').length === n, DRONES.length, 20_000);

    // A reload forgets the ticks (the selected drone only is ticked again), not the run.
    await page.reload();
    await page.locator('#conn-status.ok').waitFor({ timeout: 20_000 });
    await page.locator('#tabs [data-tab="explore"]').click();
    await until(page, (d) => document.querySelector('#exp-running')?.dataset.drones === d, DRONES.join(','), 30_000).catch(async (e) => {
      throw new Error(`after the reload: "${await page.locator('#exp-running').textContent()}", the server: ${JSON.stringify(await serverPhases())} (${e.message})`);
    });
    const ticked = await page.locator('#exp-drones input:checked').count();
    assert.ok(ticked < DRONES.length, `after a reload ${ticked} drones are ticked: the run must not depend on ticks`);
    assert.equal(await page.locator('#exp-running').textContent(), `3 drones exploring: ${DRONES.join(', ')}`);
    assert.equal(await page.locator('#btn-exp-stop-all').isDisabled(), false);
    await browser.shot('14-exploration-after-reload');
    for (const [d, phase] of Object.entries(await serverPhases())) {
      assert.ok(!['stopped', 'succeeded', 'failed', 'aborted'].includes(phase), `${d} still exploring before the stop: ${phase}`);
    }

    // One action, confirmed once, stops the whole run.
    let asked = '';
    page.once('dialog', (dlg) => {
      asked = dlg.message();
      return dlg.accept();
    });
    await page.locator('#btn-exp-stop-all').click();
    await until(page, () => /^accepted: stopped: /.test(document.querySelector('#exp-answer')?.textContent ?? ''), null, 20_000);
    assert.match(asked, /drone_0, drone_1, drone_2/);
    // The stop marks each drone of the run at once; a few polls cover the API's round trip.
    let phases = await serverPhases();
    for (let i = 0; i < 20 && !DRONES.every((d) => phases[d] === 'stopped'); i++) {
      await page.waitForTimeout(250);
      phases = await serverPhases();
    }
    assert.deepEqual(Object.keys(phases).sort(), DRONES);
    for (const d of DRONES) assert.equal(phases[d], 'stopped', `${d}: ${JSON.stringify(phases)}`);
    await until(page, () => document.querySelector('#exp-running')?.dataset.drones === '', null, 20_000);
    assert.equal(await page.locator('#exp-table tr.exploring').count(), 0);
    assert.equal(await page.locator('#btn-exp-stop-all').isDisabled(), true);
    await browser.shot('14b-exploration-run-stopped');
    assert.deepEqual(browser.pageErrors, []);
    assert.deepEqual(browser.blocked, []);
  });
});
