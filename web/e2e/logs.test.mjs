// Browser test of the Logs panel at 1024 x 768 against a real `kestrel sim` with a token that
// flies its demo mission: the live log is listed with its size; Report fetches the flight report
// with the token and shows it (the trajectory figure, drone_0's row), also in a tab of its own;
// Download saves the log, header record first; once kestrel is gone, Report says so in words.

import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { after, before, describe, test } from 'node:test';
import { openBrowser, startKestrel, until } from './harness.mjs';

describe('ground station Logs panel', { timeout: 300_000 }, () => {
  let kestrel;
  let browser;
  let page;

  before(async () => {
    kestrel = await startKestrel({ drones: 2, speedup: 5, demo: true });
    browser = await openBrowser(kestrel.base, { width: 1024, height: 768 });
    page = browser.page;
    await browser.login();
    // The demo flies takeoff, go_to, follow_path, land on each drone: wait until drone_0 landed.
    const deadline = Date.now() + 120_000;
    for (;;) {
      const { json } = await kestrel.api('GET', '/api/status');
      const m = json?.drones?.find((d) => d.drone === 'drone_0')?.mission;
      if (m && m.state === 0 && m.done_items === 4 && m.pending_items === 0) break;
      assert.ok(Date.now() < deadline, `the demo did not finish: ${JSON.stringify(m)}`);
      await new Promise((r) => setTimeout(r, 500));
    }
  });

  after(async () => {
    await browser?.close();
    await kestrel?.stop();
  });

  test('the live log is listed, with its start, size and live mark', async () => {
    await page.locator('#tabs [data-tab="logs"]').click();
    const name = path.basename(kestrel.flightLog);
    const entry = page.locator(`#logs-list .log-entry[data-log="${name}"]`);
    await entry.waitFor({ timeout: 10_000 });
    assert.equal(await entry.getAttribute('data-current'), 'true');
    assert.match(await entry.textContent(), /live/);
    // Named by --log: no start time in the name, and the panel says so.
    assert.match(await entry.locator('.log-meta').textContent(), /start unknown .* · \d+\.\d (KiB|MiB) · live/);
    const layout = await page.evaluate(() => {
      const panel = document.querySelector('#panel-logs').getBoundingClientRect();
      const boxes = [...document.querySelectorAll('#logs-list .log-entry button')].map((b) => b.getBoundingClientRect());
      return { pageScroll: document.documentElement.scrollWidth - document.documentElement.clientWidth, panel: { left: panel.left, right: panel.right }, boxes };
    });
    assert.ok(layout.pageScroll <= 0, `no horizontal page scroll (${layout.pageScroll} px)`);
    for (const b of layout.boxes) assert.ok(b.left >= layout.panel.left && b.right <= layout.panel.right + 0.5, `button inside the panel: ${JSON.stringify(b)}`);
    await browser.shot('40-logs-list');
  });

  test('Report shows the flight report fetched with the token, in the panel and in a tab', async () => {
    const name = path.basename(kestrel.flightLog);
    await page.locator(`#logs-list .log-entry[data-log="${name}"] .log-report`).click();
    const frame = page.frameLocator('#log-report-frame');
    await frame.locator('h1').waitFor({ timeout: 60_000 });
    assert.equal(await frame.locator('h1').textContent(), `Flight report: ${name}`);
    assert.equal(await frame.locator('figcaption', { hasText: 'Trajectories, coloured by the active motion behavior' }).count(), 1);
    const row = frame.locator('tr', { has: page.locator('td', { hasText: /^drone_0$/ }) });
    assert.equal(await row.count(), 1, 'a per-drone row for drone_0');
    assert.ok(Number(await row.locator('td').nth(1).textContent()) > 5, 'drone_0 flew the demo (distance flown, m)');
    assert.ok((await frame.locator('svg').count()) >= 3, 'figures inline');
    assert.match(await page.locator('#logs-answer').textContent(), /accepted: report of/);
    await browser.shot('41-logs-report');

    const [tab] = await Promise.all([page.context().waitForEvent('page'), page.locator('#log-report-open').click()]);
    await tab.waitForLoadState();
    assert.match(tab.url(), /^blob:/);
    assert.equal(await tab.locator('h1').textContent(), `Flight report: ${name}`);
    await tab.close();
    await page.locator('#log-report-close').click();
    assert.equal(await page.locator('#log-report-frame').count(), 0);
  });

  test('Download saves the log as JSON lines, header record first', async () => {
    const name = path.basename(kestrel.flightLog);
    const [download] = await Promise.all([page.waitForEvent('download'), page.locator(`#logs-list .log-entry[data-log="${name}"] .log-download`).click()]);
    assert.equal(download.suggestedFilename(), name);
    const text = fs.readFileSync(await download.path(), 'utf8');
    const lines = text.trimEnd().split('\n');
    const header = JSON.parse(lines[0]);
    assert.equal(header.type, 'header');
    assert.equal(header.command, 'sim');
    assert.ok(lines.some((l) => JSON.parse(l).type === 'pose'), 'the flight is in it');
    assert.equal(lines[0], fs.readFileSync(kestrel.flightLog, 'utf8').split('\n')[0], 'the file kestrel wrote');
  });

  test('with kestrel gone, Report says so in words', async () => {
    await kestrel.stop();
    const name = path.basename(kestrel.flightLog);
    await page.locator(`#logs-list .log-entry[data-log="${name}"] .log-report`).click();
    const text = await until(page, () => {
      const t = document.querySelector('#logs-answer')?.textContent ?? '';
      return /rejected/.test(t) && t;
    }, null, 20_000);
    assert.match(text, /report of .*: kestrel unreachable/);
    assert.match(await page.locator('#toasts').textContent(), /kestrel unreachable/);
    await browser.shot('42-logs-unreachable');
    assert.deepEqual(browser.pageErrors, []);
    assert.deepEqual(browser.blocked, []);
  });
});
