// Keyboard shortcuts: Space pauses the selected drone's mission, H holds every drone.
// Keys typed into a form field are the field's, never a command.

export type Shortcut = 'pause' | 'hold';

export interface KeyInput {
  key: string;
  ctrlKey?: boolean;
  metaKey?: boolean;
  altKey?: boolean;
  targetTag?: string;
  targetEditable?: boolean;
}

const TYPING_TAGS = new Set(['INPUT', 'TEXTAREA', 'SELECT']);

export function shortcutFor(k: KeyInput): Shortcut | null {
  if (k.ctrlKey || k.metaKey || k.altKey) return null;
  if (k.targetEditable || (k.targetTag && TYPING_TAGS.has(k.targetTag.toUpperCase()))) return null;
  if (k.key === ' ' || k.key === 'Spacebar') return 'pause';
  if (k.key === 'h' || k.key === 'H') return 'hold';
  return null;
}

export const SHORTCUT_HELP = 'Space: pause selected drone · H: hold all';
