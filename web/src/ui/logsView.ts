// Logs panel: the flight logs of the kestrel serving the page (`GET /api/logs`: name, start,
// size, which one is live), each with its report (`GET /api/logs/{name}/report`, fetched with the
// token and shown in a sandboxed frame, or opened in a tab from a Blob URL) and its download
// (`GET /api/logs/{name}`, saved through a Blob link). Failures become notices in plain words.

import { logFailure, logSummary } from '../lib/logs';
import type { LogEntry } from '../lib/types';
import type { App } from './app';
import { byId, h } from './dom';
import { act, type Outcome } from './feedback';

export class LogsView {
  private readonly list: HTMLElement;
  private readonly answer: HTMLElement;
  private readonly report: HTMLElement;
  private logs: LogEntry[] = [];
  private reportUrl: string | null = null;

  constructor(private readonly app: App) {
    const panel = byId('panel-logs');
    const refresh = h('button', { id: 'logs-refresh', type: 'button' }, 'Refresh');
    refresh.addEventListener('click', () => act(refresh, 'flight logs', this.answer, () => this.refresh()));
    this.answer = h('p', { id: 'logs-answer', className: 'answer' });
    this.list = h('ul', { id: 'logs-list', className: 'logs' });
    this.report = h('section', { id: 'log-report', hidden: true });
    panel.append(
      h('h2', {}, 'Flight logs'),
      h('p', { className: 'hint' }, 'One log per run, newest first. Report: the flight report built by kestrel. Download: the log as JSON lines.'),
      h('div', { className: 'row' }, refresh),
      this.answer,
      this.list,
      this.report,
    );
  }

  /** Fetches the list again (when the tab opens, and on Refresh). */
  async refresh(): Promise<Outcome> {
    const inst = this.app.instances[0];
    if (!inst) return { ok: false, text: 'not connected' };
    try {
      this.logs = await inst.client.logs();
    } catch (e) {
      this.list.replaceChildren();
      return { ok: false, text: logFailure('flight logs', e) };
    }
    this.render();
    return { ok: true, text: `${this.logs.length} log(s)` };
  }

  /** Fetches the list quietly (tab shown): a failure is written in the panel, no notice. */
  async show(): Promise<void> {
    const o = await this.refresh();
    if (!o.ok) {
      this.answer.className = 'answer bad';
      this.answer.textContent = o.text;
    } else if (this.answer.classList.contains('bad')) {
      this.answer.className = 'answer';
      this.answer.textContent = '';
    }
  }

  private render(): void {
    if (this.logs.length === 0) {
      this.list.replaceChildren(h('li', { className: 'hint' }, 'No flight log yet.'));
      return;
    }
    this.list.replaceChildren(
      ...this.logs.map((e) => {
        const report = h('button', { type: 'button', className: 'small log-report' }, 'Report');
        const download = h('button', { type: 'button', className: 'small log-download' }, 'Download');
        report.addEventListener('click', () => act(report, `report of ${e.name}`, this.answer, () => this.showReport(e.name)));
        download.addEventListener('click', () => act(download, `download of ${e.name}`, this.answer, () => this.download(e.name)));
        return h(
          'li',
          { className: `log-entry${e.current ? ' current' : ''}`, 'data-log': e.name, 'data-current': String(e.current) },
          h('span', { className: 'log-name' }, e.name),
          e.current ? h('span', { className: 'badge ok' }, 'live') : null,
          h('span', { className: 'log-meta' }, logSummary(e)),
          h('span', { className: 'log-actions' }, report, download),
        );
      }),
    );
  }

  private async showReport(name: string): Promise<Outcome> {
    const inst = this.app.instances[0];
    if (!inst) return { ok: false, text: 'not connected' };
    let html: string;
    try {
      html = await inst.client.logReport(name);
    } catch (e) {
      return { ok: false, text: logFailure(`report of ${name}`, e) };
    }
    if (this.reportUrl) URL.revokeObjectURL(this.reportUrl);
    this.reportUrl = URL.createObjectURL(new Blob([html], { type: 'text/html' }));
    // The report is self-contained (figures inline, no script): a frame without any permission.
    const frame = h('iframe', { id: 'log-report-frame', title: `flight report of ${name}`, sandbox: '' });
    frame.srcdoc = html;
    const close = h('button', { type: 'button', className: 'small', id: 'log-report-close' }, 'Close');
    close.addEventListener('click', () => this.closeReport());
    this.report.replaceChildren(
      h(
        'div',
        { className: 'row' },
        h('strong', { className: 'log-name' }, `Report: ${name}`),
        h('a', { id: 'log-report-open', href: this.reportUrl, target: '_blank', rel: 'noopener' }, 'Open in new tab'),
        close,
      ),
      frame,
    );
    this.report.hidden = false;
    this.report.scrollIntoView({ block: 'nearest' });
    return { ok: true, text: `report of ${name} shown below the list` };
  }

  private closeReport(): void {
    this.report.hidden = true;
    this.report.replaceChildren();
    if (this.reportUrl) URL.revokeObjectURL(this.reportUrl);
    this.reportUrl = null;
  }

  private async download(name: string): Promise<Outcome> {
    const inst = this.app.instances[0];
    if (!inst) return { ok: false, text: 'not connected' };
    try {
      const { filename, blob } = await inst.client.logFile(name);
      const url = URL.createObjectURL(blob);
      const a = h('a', { href: url, download: filename });
      document.body.append(a);
      a.click();
      a.remove();
      setTimeout(() => URL.revokeObjectURL(url), 60_000);
      return { ok: true, text: `${filename} saved` };
    } catch (e) {
      return { ok: false, text: logFailure(`download of ${name}`, e) };
    }
  }
}
