import { defineConfig } from 'vite';

// Served by the mentalsim binary under /console/ (same origin as the API).
export default defineConfig({
  base: '/console/',
  build: {
    outDir: 'dist',
    emptyOutDir: true,
    target: 'es2022',
    sourcemap: false,
    // YASGUI is one prebuilt ~1.3 MB module, loaded only on the knowledge page.
    chunkSizeWarningLimit: 2000,
    rollupOptions: {
      onwarn(warning, warn) {
        // YASGUI's bundled JSON polyfill uses direct eval; not our code.
        if (warning.code === 'EVAL' && /yasgui/.test(warning.id ?? '')) return;
        warn(warning);
      },
    },
  },
  server: {
    // `npm run dev` against a service on :8080.
    proxy: {
      '/v1': 'http://127.0.0.1:8080',
      '/sparql': 'http://127.0.0.1:8080',
      '/openapi.json': 'http://127.0.0.1:8080',
    },
  },
});
