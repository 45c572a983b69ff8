// Browser tests of the ground station against a real `kestrel sim --no-demo --drones 2`: the
// operator's main flows, driven by clicks in Debian's chromium. Screenshots go to artifacts/web/.

import assert from 'node:assert/strict';
import fs from 'node:fs';
import { after, before, describe, test } from 'node:test';
import { clickMapAt, openBrowser, startKestrel, until } from './harness.mjs';

const MISSION_TIMEOUT = 120_000;

describe('ground station against kestrel sim', { timeout: 600_000 }, () => {
  let kestrel;
  let browser;
  let page;

  before(async () => {
    kestrel = await startKestrel({ drones: 2, speedup: 5 });
    browser = await openBrowser(kestrel.base);
    page = browser.page;
  });

  after(async () => {
    await browser?.close();
    await kestrel?.stop();
  });

  /** Mission state and item rows of one drone, as the Monitor panel shows them. */
  const monitorOf = (drone) =>
    page.evaluate((d) => {
      const sec = document.querySelector(`.mstatus[data-drone="${d}"]`);
      if (!sec) return null;
      const items = [...sec.querySelectorAll('.mitem')].map((li) => li.className.replace('mitem ', ''));
      return { state: sec.getAttribute('data-state'), items };
    }, drone);

  const waitFinished = (drone, count, timeout = MISSION_TIMEOUT) =>
    until(
      page,
      ([d, n]) => {
        const sec = document.querySelector(`.mstatus[data-drone="${d}"]`);
        return sec && sec.getAttribute('data-state') === 'idle' && sec.querySelectorAll('.mitem.done').length === n;
      },
      [drone, count],
      timeout,
    );

  const markerOf = (drone) =>
    page.evaluate((d) => {
      const el = document.querySelector(`.drone-glyph[data-drone="${d}"]`);
      return el ? { x: Number(el.dataset.x), y: Number(el.dataset.y), lost: el.classList.contains('lost') } : null;
    }, drone);

  const tab = (name) => page.locator(`#tabs [data-tab="${name}"]`).click();

  const planFor = async (drone) => {
    await tab('plan');
    await page.locator('#plan-clear').click();
    await page.locator('#plan-target').selectOption({ label: drone });
  };

  test('asks the token once and shows both drones live', async () => {
    await page.locator('#token-dialog[open]').waitFor();
    await browser.shot('00-token');
    await browser.login();
    for (const d of ['drone_0', 'drone_1']) {
      await page.locator(`.card[data-drone="${d}"][data-link="ok"]`).waitFor({ timeout: 20_000 });
    }
    await until(page, () => document.querySelectorAll('.drone-glyph').length === 2);
    await browser.shot('01-fleet');
    // Reloading keeps the session's token: no second prompt.
    await page.reload();
    await page.locator('#conn-status.ok').waitFor({ timeout: 20_000 });
    assert.equal(await page.locator('#token-dialog[open]').count(), 0);
  });

  test('plans takeoff, go_to, land by clicking the map; uploads, starts, flies and finishes', async () => {
    await planFor('drone_0');
    await page.locator('#plan-height').fill('3');
    await page.locator('#plan-speed').fill('2');
    await page.locator('#add-takeoff').click();
    await page.locator('#tool-waypoint').click();
    const start = await markerOf('drone_0');
    const goal = { x: start.x + 6, y: start.y + 4 };
    await clickMapAt(page, goal.x, goal.y);
    await page.locator('#add-land').click();
    await page.locator('[data-tool="pan"]').click();
    const behaviors = await page.locator('#plan-items .item-behavior').evaluateAll((els) => els.map((e) => e.value));
    assert.deepEqual(behaviors, ['takeoff', 'go_to', 'land']);
    const x = Number(await page.locator('#arg-1-x').inputValue());
    const y = Number(await page.locator('#arg-1-y').inputValue());
    assert.ok(Math.abs(x - goal.x) < 0.5 && Math.abs(y - goal.y) < 0.5, `waypoint (${x}, ${y}) is where the map was clicked (${goal.x}, ${goal.y})`);
    await browser.shot('02-plan');

    await page.locator('#btn-upload').click();
    await until(page, () => /^accepted/.test(document.querySelector('#plan-answer')?.textContent ?? ''), null, 20_000);
    await tab('control');
    await page.locator('#ctl-drone').selectOption({ label: 'drone_0' });
    await page.locator('#ctl-buttons [data-action="START"]').click();
    await until(page, () => /^accepted/.test(document.querySelector('#ctl-answer')?.textContent ?? ''), null, 20_000);
    await browser.shot('03-control');

    // The marker moves toward the waypoint.
    await until(
      page,
      ([gx, gy]) => {
        const el = document.querySelector('.drone-glyph[data-drone="drone_0"]');
        return el && Math.hypot(Number(el.dataset.x) - gx, Number(el.dataset.y) - gy) < 1.0;
      },
      [goal.x, goal.y],
      MISSION_TIMEOUT,
    );
    await tab('monitor');
    await waitFinished('drone_0', 3);
    const m = await monitorOf('drone_0');
    assert.deepEqual(m.items, ['done', 'done', 'done']);
    await browser.shot('04-monitor');
    await tab('timeline');
    await until(page, () => document.querySelectorAll('#timeline-live rect[data-behavior="go_to"]').length > 0, null, 10_000);
    await browser.shot('05-timeline');
    await page.locator('#btn-fetch-log').click();
    await until(page, () => /^accepted/.test(document.querySelector('#log-answer')?.textContent ?? ''), null, 20_000);
    await browser.shot('06-timeline-past');
  });

  test('pauses and resumes from the buttons, and holds with the H key', async () => {
    await planFor('drone_1');
    await page.locator('#plan-speed').fill('0.5');
    await page.locator('#add-takeoff').click();
    await page.locator('#tool-waypoint').click();
    const start = await markerOf('drone_1');
    await clickMapAt(page, start.x - 8, start.y + 8);
    await page.locator('#add-land').click();
    await page.locator('[data-tool="pan"]').click();
    await page.locator('#btn-upload-start').click();
    await until(page, () => /^accepted/.test(document.querySelector('#plan-answer')?.textContent ?? ''), null, 20_000);

    await tab('monitor');
    await until(page, () => document.querySelector('.mstatus[data-drone="drone_1"] .mitem.current')?.textContent?.includes('go_to'), null, MISSION_TIMEOUT);
    await tab('control');
    await page.locator('#ctl-drone').selectOption({ label: 'drone_1' });
    await page.locator('#ctl-buttons [data-action="PAUSE"]').click();
    await until(page, () => /^accepted/.test(document.querySelector('#ctl-answer')?.textContent ?? ''), null, 20_000);
    await until(page, () => document.querySelector('.mstatus[data-drone="drone_1"]')?.getAttribute('data-state') === 'paused', null, 20_000);
    await page.waitForTimeout(1000);
    const a = await markerOf('drone_1');
    await page.waitForTimeout(1500);
    const b = await markerOf('drone_1');
    assert.ok(Math.hypot(a.x - b.x, a.y - b.y) < 0.8, `paused drone holds (moved ${Math.hypot(a.x - b.x, a.y - b.y).toFixed(2)} m)`);
    await browser.shot('07-paused');

    await page.locator('#ctl-buttons [data-action="RESUME"]').click();
    await until(page, () => document.querySelector('.mstatus[data-drone="drone_1"]')?.getAttribute('data-state') === 'running', null, 20_000);

    // H holds every drone (drone_1 is the only one flying a mission).
    await page.locator('#map').click({ position: { x: 5, y: 5 } });
    await page.keyboard.press('h');
    await until(page, () => document.querySelector('.mstatus[data-drone="drone_1"]')?.getAttribute('data-state') === 'paused', null, 20_000);
    await page.locator('#ctl-buttons [data-action="RESUME"]').click();
    await tab('monitor');
    await waitFinished('drone_1', 3);
  });

  test("shows the API's validation error beside the field; exports, imports and edits the JSON", async () => {
    await planFor('drone_0');
    await page.locator('#add-takeoff').click();
    await page.locator('#tool-waypoint').click();
    await clickMapAt(page, 2, 2);
    await page.locator('[data-tool="pan"]').click();
    await page.locator('#arg-1-speed').fill('-1');
    await page.locator('#arg-1-speed').press('Tab');
    await page.locator('#btn-upload').click();
    const err = page.locator('#plan-items .item[data-index="1"] .field[data-field="speed"] .field-error');
    await until(page, () => (document.querySelector('#plan-items .item[data-index="1"] .field[data-field="speed"] .field-error')?.textContent ?? '') !== '', null, 20_000);
    const text = await err.textContent();
    assert.match(text, /speed/i);
    assert.match(await page.locator('#plan-answer').textContent(), /^rejected/);
    assert.equal(await page.locator('#plan-items .item[data-index="0"] .field-error:not(:empty)').count(), 0, 'no error shown on the valid item');
    await browser.shot('08-validation-error');

    // Export the mission to a file, clear the plan, import the file back.
    await page.locator('#json-details summary').click();
    const json = JSON.parse(await page.locator('#mission-json').inputValue());
    assert.equal(json.plan[1].args.speed, -1);
    const [download] = await Promise.all([page.waitForEvent('download'), page.locator('#btn-export').click()]);
    const file = await download.path();
    await page.locator('#plan-clear').click();
    assert.equal(await page.locator('#plan-items .item').count(), 0);
    await page.locator('#import-file').setInputFiles(file);
    await until(page, () => document.querySelectorAll('#plan-items .item').length === 2, null, 5_000);
    assert.match(await page.locator('#json-answer').textContent(), /^accepted: .*2 item\(s\) imported/);
    // The JSON editor: fix the speed by hand and apply.
    const fixed = { ...json, plan: [json.plan[0], { ...json.plan[1], args: { ...json.plan[1].args, speed: 1.5 } }] };
    await page.locator('#mission-json').fill(JSON.stringify(fixed));
    await page.locator('#btn-apply-json').click();
    assert.equal(await page.locator('#arg-1-speed').inputValue(), '1.5');
    await browser.shot('09-json-editor');
    await page.locator('#json-details summary').click();
  });

  test('a polygon becomes a two-drone coverage mission that both drones fly', async (t) => {
    const probe = await kestrel.api('POST', '/api/coverage', { polygon_enu_m: [[0, 0], [4, 0], [4, 4]], street_spacing_m: 2, angle_deg: null, drones: ['drone_0'], height_m: 3 });
    if (probe.status === 404 || probe.status === 405) {
      t.skip(`this kestrel has no POST /api/coverage yet (HTTP ${probe.status})`);
      return;
    }
    await planFor('drone_0');
    await page.locator('#plan-height').fill('4');
    await page.locator('#plan-speed').fill('2');
    await page.locator('#tool-polygon').click();
    for (const [x, y] of [[-6, 6], [6, 6], [6, 14], [-6, 14]]) await clickMapAt(page, x, y);
    await page.locator('#tool-finish').click();
    await page.locator('#coverage:not([hidden])').waitFor();
    await page.locator('#cov-spacing').fill('4');
    await page.locator('#btn-coverage').click();
    await until(page, () => /^accepted/.test(document.querySelector('#cov-answer')?.textContent ?? ''), null, 20_000);
    assert.equal(await page.locator('#cov-summary li').count(), 2);
    await browser.shot('10-coverage-plan');
    await page.locator('#btn-coverage-go').click();
    await until(page, () => /^accepted/.test(document.querySelector('#cov-answer')?.textContent ?? ''), null, 30_000);
    await tab('monitor');
    await until(page, () => ['drone_0', 'drone_1'].every((d) => document.querySelector(`.mstatus[data-drone="${d}"] .mitem.current`)?.textContent?.includes('follow_path')), null, MISSION_TIMEOUT);
    await browser.shot('11-coverage-flying');
    await waitFinished('drone_0', 4, 240_000);
    await waitFinished('drone_1', 4, 240_000);
    await browser.shot('12-coverage-done');
  });

  test('an on-demand task inspects a registered panel with the drone the operator picks', async () => {
    await tab('control');
    await page.locator('#frame-details summary').click();
    await page.locator('#frame-id').fill('panel_7');
    await page.locator('#frame-x').fill('4');
    await page.locator('#frame-y').fill('-4');
    await page.locator('#btn-frame').click();
    await until(page, () => /^accepted/.test(document.querySelector('#frame-answer')?.textContent ?? ''), null, 20_000);
    const frames = await kestrel.api('GET', '/api/frames');
    assert.ok(frames.json.some((f) => f.frame_id === 'panel_7'), JSON.stringify(frames.json));
    await until(page, () => [...document.querySelectorAll('#od-frame option')].some((o) => o.value === 'panel_7'), null, 20_000);
    await until(page, () => [...document.querySelectorAll('.frame-icon')].some((e) => e.textContent.includes('panel_7')), null, 10_000);
    await page.locator('#od-frame').selectOption('panel_7');
    await page.locator('#od-drone').selectOption({ label: 'drone_0' });
    await page.locator('#od-approach').fill('5');
    await page.locator('#od-height').fill('2');
    await page.locator('#btn-inspect').click();
    await until(page, () => /^accepted/.test(document.querySelector('#od-answer')?.textContent ?? ''), null, 20_000);
    await until(
      page,
      () => {
        const el = document.querySelector('.drone-glyph[data-drone="drone_0"]');
        return el && Math.hypot(Number(el.dataset.x) - 4, Number(el.dataset.y) + 4) < 0.6;
      },
      null,
      MISSION_TIMEOUT,
    );
    await browser.shot('13-on-demand');
    await tab('monitor');
    const n = await page.evaluate(() => document.querySelectorAll('.mstatus[data-drone="drone_0"] .mitem').length);
    await waitFinished('drone_0', n);
  });

  test('explores with a chosen drone: frontiers, its goal and the growing area on the map, a report, a confirmed stop', async () => {
    // One selected drone for the whole page (earlier tests selected drone_1 in Control): until
    // the operator ticks here, the Explore panel ticks the selected drone only.
    await page.locator('#drone-select').selectOption({ label: 'drone_0' });
    await tab('explore');
    await until(page, () => document.querySelectorAll('#exp-drones input[type=checkbox]').length === 2, null, 10_000);
    assert.equal(await page.locator('#exp-drones input[data-drone="drone_0"]').isChecked(), true);
    assert.equal(await page.locator('#exp-drones input[data-drone="drone_1"]').isChecked(), false);
    await page.locator('#exp-drones input[data-drone="drone_0"]').uncheck();
    await page.locator('#exp-drones input[data-drone="drone_1"]').check();
    await page.locator('#btn-exp-start').click();
    await until(page, () => /^accepted: exploring: drone_1/.test(document.querySelector('#exp-answer')?.textContent ?? ''), null, 20_000);
    // Frontiers and drone_1's goal, with the line from the drone to it, drawn on the map.
    await until(page, () => document.querySelectorAll('path.frontier').length > 0 && document.querySelector('path.explore-goal-drone_1') !== null, null, MISSION_TIMEOUT);
    const row = await page.locator('#exp-table tr[data-drone="drone_1"]').getAttribute('data-phase');
    assert.ok(['takeoff', 'navigating', 'sensing', 'drone_avoidance'].includes(row), row);
    assert.equal(await page.locator('#exp-table tr[data-drone="drone_0"]').count(), 0, 'drone_0 was not ticked');
    // The known area grows, and so does the elapsed time; an estimate appears.
    const pct0 = Number(await page.locator('#exp-known').getAttribute('data-pct'));
    const s0 = Number(await page.locator('#exp-elapsed').getAttribute('data-s'));
    await until(page, (p0) => Number(document.querySelector('#exp-known')?.dataset.pct) > p0 + 0.05, pct0, MISSION_TIMEOUT);
    assert.ok(Number(await page.locator('#exp-elapsed').getAttribute('data-s')) > s0);
    await until(page, () => /^≤ /.test(document.querySelector('#exp-remaining')?.textContent ?? ''), null, MISSION_TIMEOUT);
    await browser.shot('13b-exploring');
    // The report downloads as a file.
    const [download] = await Promise.all([page.waitForEvent('download'), page.locator('#btn-exp-report').click()]);
    assert.match(download.suggestedFilename(), /^kestrel-exploration-\d+\.json$/);
    const report = JSON.parse(fs.readFileSync(await download.path(), 'utf8'));
    assert.deepEqual(report.drones.map((d) => d.drone), ['drone_1']);
    assert.ok(report.area_curve.length >= 2 && report.area_curve.at(-1).area_pct > report.area_curve[0].area_pct, JSON.stringify(report.area_curve.slice(0, 3)));
    assert.ok(report.drones[0].path_m > 0);
    assert.ok('evaluation' in report);

    // drone_0 joins; stopping both asks first: cancelled, nothing stops; confirmed, both stop.
    await page.locator('#exp-drones input[data-drone="drone_0"]').check();
    await page.locator('#btn-exp-start').click();
    await until(page, () => /^accepted: exploring: drone_0/.test(document.querySelector('#exp-answer')?.textContent ?? ''), null, 20_000);
    await until(page, () => document.querySelectorAll('#exp-table tr.exploring').length === 2, null, 20_000);
    page.once('dialog', (d) => d.dismiss());
    await page.locator('#btn-exp-stop').click();
    await until(page, () => /^rejected: not stopped/.test(document.querySelector('#exp-answer')?.textContent ?? ''), null, 10_000);
    await page.waitForTimeout(1500);
    assert.equal(await page.locator('#exp-table tr.exploring').count(), 2, 'a cancelled stop stops nothing');
    let asked = '';
    page.once('dialog', (d) => {
      asked = d.message();
      return d.accept();
    });
    await page.locator('#btn-exp-stop').click();
    await until(page, () => /^accepted: stopped/.test(document.querySelector('#exp-answer')?.textContent ?? ''), null, 20_000);
    assert.match(asked, /drone_0, drone_1/);
    await until(page, () => document.querySelectorAll('#exp-table tr').length === 2 && document.querySelectorAll('#exp-table tr.exploring').length === 0, null, 20_000);
    await until(page, () => document.querySelector('path.explore-goal-drone_1') === null, null, 20_000);
    await browser.shot('13c-exploration-stopped');
  });

  test('a drone whose link is lost is shown as lost, and live again when restored', async () => {
    await tab('fleet');
    const r = await kestrel.api('POST', '/api/sim/fault', { drone_id: 'drone_1', fault: 'link_lost' });
    assert.equal(r.status, 200, JSON.stringify(r.json));
    await page.locator('.card[data-drone="drone_1"][data-link="lost"]').waitFor({ timeout: 20_000 });
    assert.match(await page.locator('.card[data-drone="drone_1"] [data-field="link"]').textContent(), /LOST/);
    await until(page, () => document.querySelector('.drone-glyph[data-drone="drone_1"]')?.classList.contains('lost'), null, 5_000);
    assert.equal(await page.locator('.card[data-drone="drone_0"]').getAttribute('data-link'), 'ok');
    await browser.shot('14-link-lost');
    await kestrel.api('POST', '/api/sim/fault', { drone_id: 'drone_1', fault: 'link_restored' });
    await page.locator('.card[data-drone="drone_1"][data-link="ok"]').waitFor({ timeout: 30_000 });
  });

  test('works on a tablet-sized screen', async () => {
    await page.setViewportSize({ width: 820, height: 1180 });
    await page.waitForTimeout(500);
    await browser.shot('15-tablet');
    assert.ok(await page.locator('#btn-hold-all').isVisible());
    assert.ok(await page.locator('#btn-land-all').isVisible());
    await page.setViewportSize({ width: 1400, height: 900 });
  });

  test('when kestrel goes away every drone is shown as lost', async () => {
    await tab('fleet');
    await kestrel.stop();
    for (const d of ['drone_0', 'drone_1']) {
      await page.locator(`.card[data-drone="${d}"][data-link="lost"]`).waitFor({ timeout: 20_000 });
    }
    await page.locator('#conn-status.bad').waitFor({ timeout: 5_000 });
    await browser.shot('16-kestrel-gone');
  });

  test('no request left localhost and the page raised no error', () => {
    assert.deepEqual(browser.blocked, []);
    assert.deepEqual(browser.pageErrors, []);
  });
});
