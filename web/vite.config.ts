import { defineConfig } from 'vitest/config';

// The page is served by kestrel at `/` (embedded or from `dist/` next to the binary); relative
// asset paths keep it working under any prefix. `npm run dev` proxies the API to a local kestrel.
export default defineConfig({
  base: './',
  build: { outDir: 'dist', emptyOutDir: true, chunkSizeWarningLimit: 600 },
  server: {
    proxy: {
      '/api': { target: process.env.KESTREL_URL ?? 'http://127.0.0.1:8080', ws: true },
    },
  },
  test: { include: ['test/**/*.test.ts'], environment: 'node' },
});
