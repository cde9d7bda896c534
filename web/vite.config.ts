import { defineConfig } from 'vite';
import { VitePWA } from 'vite-plugin-pwa';

// The app is served by the omninav server at / (web/dist). `npm run dev -w web` proxies the API.
export default defineConfig({
  base: '/',
  build: {
    target: 'es2022',
    // opencv.js is one 13 MB module (WASM inlined); it loads in the worker only, off the main thread
    chunkSizeWarningLimit: 16_000,
    // admin.html: the admin page (/admin, served by omninav serve), a second entry sharing src/shared
    rollupOptions: { input: { main: 'index.html', selftest: 'selftest.html', admin: 'admin.html' } },
  },
  worker: { format: 'es' },
  server: { proxy: { '/api': 'http://127.0.0.1:8000' } },
  plugins: [
    VitePWA({
      registerType: 'autoUpdate',
      injectRegister: false, // registered in main.ts, where a failure can be reported
      includeAssets: ['icon.svg'],
      manifest: {
        name: 'omninav: where am I?',
        short_name: 'omninav',
        description:
          'Indoor localisation for blind and visually impaired people: where you are and what is around, spoken.',
        lang: 'en',
        start_url: '/',
        scope: '/',
        display: 'standalone',
        orientation: 'portrait',
        background_color: '#000000',
        theme_color: '#000000',
        icons: [
          { src: 'icon-192.png', sizes: '192x192', type: 'image/png' },
          { src: 'icon-512.png', sizes: '512x512', type: 'image/png' },
          { src: 'icon-512.png', sizes: '512x512', type: 'image/png', purpose: 'maskable' },
          { src: 'icon.svg', sizes: 'any', type: 'image/svg+xml' },
        ],
      },
      workbox: {
        // the shell, the worker and opencv.js (WASM inside) are precached: the app opens offline
        globPatterns: ['**/*.{js,css,html,svg,png,webmanifest}'],
        // not the admin page (its entry and CSS, Leaflet's images inlined): no phone opens it, and
        // its 185 kB would be downloaded again by every phone on each change of the admin page
        globIgnores: ['admin.html', 'assets/admin-*'],
        maximumFileSizeToCacheInBytes: 20 * 1024 * 1024,
        navigateFallback: '/index.html',
        navigateFallbackDenylist: [/^\/api\//, /^\/admin(\/|$)/],
        cleanupOutdatedCaches: true,
        // the first visit's page is controlled at once, so it opens offline next time without a reload
        clientsClaim: true,
        skipWaiting: true,
      },
    }),
  ],
});
