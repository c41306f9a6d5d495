// node view.js MODEL.glb OUT.png [eye=x,y,z target=x,y,z fov=deg w=px h=px]
// Serves three.js and the model on localhost, renders it in headless Chromium (software
// WebGL), saves a screenshot.
const http = require('http'), fs = require('fs'), path = require('path');
const puppeteer = require('puppeteer-core');
const [model, out, ...rest] = process.argv.slice(2);
if (!model || !out) { console.error('usage: node view.js MODEL.glb OUT.png [key=value ...]'); process.exit(2); }
const query = rest.join('&');
const root = __dirname, three = path.join(root, 'node_modules', 'three');
const types = { '.js': 'text/javascript', '.html': 'text/html' };
const server = http.createServer((req, res) => {
  const url = decodeURIComponent(req.url.split('?')[0]);
  let file = url === '/model' ? path.resolve(model)
    : url.startsWith('/three/') ? path.join(three, url.slice(7)) : path.join(root, 'view.html');
  fs.readFile(file, (err, data) => {
    if (err) { res.writeHead(404); res.end(); return; }
    res.writeHead(200, { 'Content-Type': types[path.extname(file)] || 'application/octet-stream' });
    res.end(data);
  });
}).listen(0, async () => {
  const port = server.address().port;
  const browser = await puppeteer.launch({
    executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
    args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist'],
  });
  try {
    const page = await browser.newPage();
    const w = Number((query.match(/w=(\d+)/) || [])[1] || 1024), h = Number((query.match(/h=(\d+)/) || [])[1] || 768);
    await page.setViewport({ width: w, height: h });
    page.on('console', (m) => console.error('page:', m.text()));
    await page.goto(`http://localhost:${port}/?${query}`);
    await page.waitForFunction(() => document.title !== '', { timeout: 300000 });
    const title = await page.title();
    if (title !== 'rendered') throw new Error(title);
    await page.screenshot({ path: out });
    console.log(`three.js r${require(path.join(three, 'package.json')).version} in ${await browser.version()}: wrote ${out}`);
  } finally { await browser.close(); server.close(); }
});
