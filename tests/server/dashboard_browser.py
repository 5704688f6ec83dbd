#!/usr/bin/python3
"""The dashboard (invr-server --http-address) in a real browser: Debian's chromium, headless,
driven through the Chrome DevTools protocol.

A server with client and worker tokens, one worker and a small job with snapshots whose name
holds markup. Checked over HTTP: the API refuses calls without a token or with a wrong one, the
sign-in sets an HttpOnly, SameSite=Strict cookie (and refuses non-JSON or cross-origin posts),
only listed result files are served, and no token reaches the server's log. Checked in the
browser: the sign-in form refuses a wrong token; the job list shows the job (submitted by the
token's name) with its name as text; the job page's charts get points and more points, the
snapshot and target images load, their difference is drawn, and the snapshot moves on to a later
step; the workers page lists the worker. A screenshot of each page is saved under OUT_DIR.

usage: dashboard_browser.py BIN_DIR OUT_DIR [--measure]
--measure adds the figures of docs/dashboard.md: the job list's load time with 100 jobs, and
the server's memory over a 3000-step job with its page open (against the same job unwatched).
"""
import base64
import http.client as httpclient
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request

import websocket  # python3-websocket

BIN, OUT = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
MEASURE = "--measure" in sys.argv[3:]
CLIENT_TOKEN = "dash-client-" + os.urandom(8).hex()
WORKER_TOKEN = "dash-worker-" + os.urandom(8).hex()
NAME = 'oxalis <script>window.__xss=1</script><img src=x onerror="window.__xss=2">'

procs = []
work = tempfile.mkdtemp(prefix="invr-dashboard-")


def fail(msg):
    print("dashboard: FAILED:", msg)
    for f in sorted(os.listdir(work)):
        if f.endswith(".log"):
            print("==", f)
            print(open(os.path.join(work, f), errors="replace").read()[-3000:])
    sys.exit(1)


def check(cond, msg):
    if not cond:
        fail(msg)
    print("ok:", msg)


def cleanup():
    for p in procs:
        try:
            p.kill()
        except Exception:
            pass
    shutil.rmtree(work, ignore_errors=True)


def start_server(tag, extra=(), http="127.0.0.1:0"):
    log = open(os.path.join(work, tag + ".log"), "w")
    p = subprocess.Popen([os.path.join(BIN, "invr-server"), "--store", os.path.join(work, tag + "-store"), "--address", "127.0.0.1:0",
                          "--http-address", http, "--client-token-file", os.path.join(work, "clients.tok"),
                          "--worker-token-file", os.path.join(work, "worker.tok"), "--final-spp", "8", *extra],
                         stdout=subprocess.PIPE, stderr=log, text=True)
    procs.append(p)
    port = url = None
    deadline = time.time() + 30
    while time.time() < deadline and not url:
        line = p.stdout.readline()
        if not line:
            break
        if m := re.search(r"listening on port (\d+)", line):
            port = int(m.group(1))
        if m := re.search(r"dashboard at (\S+)", line):
            url = m.group(1)
    if not (port and url):
        fail(f"{tag}: the server did not print its port and dashboard address")
    return p, f"127.0.0.1:{port}", url


def start_worker(grpc_addr, tag):
    log = open(os.path.join(work, tag + ".log"), "w")
    p = subprocess.Popen([os.path.join(BIN, "invr-worker"), "--server", grpc_addr, "--token-file", os.path.join(work, "worker.tok"),
                          "--threads", "1", "--name", tag], stdout=log, stderr=log)
    procs.append(p)
    return p


def invr(*args, check_rc=True):
    env = dict(os.environ, INVR_TOKEN=CLIENT_TOKEN)
    r = subprocess.run([os.path.join(BIN, "invr"), *args], capture_output=True, text=True, env=env)
    if check_rc and r.returncode != 0:
        fail(f"invr {' '.join(args)}: exit {r.returncode}: {r.stderr[-2000:]}")
    return r.stdout


def submit(grpc_addr, job_file):
    out = invr("submit", job_file, "--server", grpc_addr)
    m = re.search(r"(job-\d+)", out)
    if not m:
        fail("submit printed no job id: " + out)
    return m.group(1)


def http(url, method="GET", body=None, headers=None):
    req = urllib.request.Request(url, data=body, method=method, headers=headers or {})
    try:
        with urllib.request.urlopen(req, timeout=20) as r:
            return r.status, dict(r.headers), r.read()
    except urllib.error.HTTPError as e:
        return e.code, dict(e.headers), e.read()


def api(url, path):
    status, _, body = http(url.rstrip("/") + path, headers={"Authorization": "Bearer " + CLIENT_TOKEN})
    if status != 200:
        fail(f"GET {path}: {status} {body[:300]!r}")
    return json.loads(body)


class Browser:
    """chromium --headless with a DevTools websocket to its one page."""

    def __init__(self):
        exe = shutil.which("chromium") or fail("chromium is not installed (deploy/setup.sh installs it)")
        self.profile = os.path.join(work, "chromium-profile")
        log = open(os.path.join(work, "chromium.log"), "w")
        self.proc = subprocess.Popen([exe, "--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run", "--no-default-browser-check",
                                      "--disable-extensions", "--disable-background-networking", "--remote-debugging-port=0",
                                      "--remote-allow-origins=*", "--user-data-dir=" + self.profile, "--window-size=1280,900",
                                      "about:blank"], stdout=log, stderr=log)
        procs.append(self.proc)
        port_file = os.path.join(self.profile, "DevToolsActivePort")
        for _ in range(300):
            if os.path.exists(port_file) and open(port_file).read().strip():
                break
            time.sleep(0.1)
        else:
            fail("chromium did not open its DevTools port")
        port = int(open(port_file).read().split()[0])
        pages = []
        for _ in range(100):
            pages = [t for t in json.loads(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list").read()) if t["type"] == "page"]
            if pages:
                break
            time.sleep(0.1)
        self.ws = websocket.create_connection(pages[0]["webSocketDebuggerUrl"], timeout=60, suppress_origin=True)
        self.next_id = 0
        self.send("Page.enable")
        self.send("Runtime.enable")
        self.send("Emulation.setDeviceMetricsOverride", width=1280, height=900, deviceScaleFactor=1, mobile=False)

    def send(self, method, **params):
        self.next_id += 1
        self.ws.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv())
            if msg.get("id") == self.next_id:
                if "error" in msg:
                    fail(f"DevTools {method}: {msg['error']}")
                return msg.get("result", {})

    def eval(self, expr):
        r = self.send("Runtime.evaluate", expression=expr, returnByValue=True, awaitPromise=True)
        if "exceptionDetails" in r:
            fail(f"page script {expr!r}: {r['exceptionDetails'].get('exception', {}).get('description', r['exceptionDetails'])}")
        return r["result"].get("value")

    def wait(self, expr, what, timeout=90):
        deadline = time.time() + timeout
        while time.time() < deadline:
            v = self.eval(expr)
            if v:
                return v
            time.sleep(0.25)
        self.screenshot("timeout.png")
        fail(f"timed out waiting for {what} ({expr})")

    def navigate(self, url):
        self.send("Page.navigate", url=url)

    def screenshot(self, name):
        data = self.send("Page.captureScreenshot", format="png", captureBeyondViewport=True)["data"]
        path = os.path.join(OUT, name)
        with open(path, "wb") as f:
            f.write(base64.b64decode(data))
        print("screenshot:", path)


def main():
    os.makedirs(OUT, exist_ok=True)
    with open(os.path.join(work, "clients.tok"), "w") as f:
        f.write("# name token\nalice " + CLIENT_TOKEN + "\nbob dash-bob-" + os.urandom(8).hex() + "\n")
    with open(os.path.join(work, "worker.tok"), "w") as f:
        f.write(WORKER_TOKEN + "\n")
    _, grpc_addr, url = start_server("server")
    start_worker(grpc_addr, "worker-1")

    job = json.loads(invr("example", "oxalis"))
    job["name"] = NAME
    job.setdefault("optimization", {})["steps"] = 400
    job["optimization"]["snapshot_every"] = 4
    job_file = os.path.join(work, "job.json")
    json.dump(job, open(job_file, "w"))
    job_id = submit(grpc_addr, job_file)

    # ---- over HTTP
    base = url.rstrip("/")
    check(http(base + "/api/jobs")[0] == 401, "the API refuses a call without a token")
    check(http(base + "/api/jobs", headers={"Authorization": "Bearer nope"})[0] == 401, "the API refuses a wrong bearer token")
    check(http(base + "/api/jobs", headers={"Authorization": "Bearer " + WORKER_TOKEN})[0] == 401, "the API refuses the worker token")
    jobs = api(url, "/api/jobs")["jobs"]
    mine = [j for j in jobs if j["job_id"] == job_id]
    check(len(mine) == 1 and mine[0]["name"] == NAME, "the job list has the job under its name, as sent")
    check(mine[0]["submitted_by"] == "alice", "the job was submitted by the token's name (alice)")
    st, headers, _ = http(base + "/api/login", "POST", json.dumps({"token": CLIENT_TOKEN}).encode(), {"Content-Type": "text/plain"})
    check(st == 415, "sign-in refuses a non-JSON body (a cross-site form cannot post it)")
    st, _, _ = http(base + "/api/login", "POST", json.dumps({"token": CLIENT_TOKEN}).encode(),
                    {"Content-Type": "application/json", "Origin": "http://evil.example"})
    check(st == 403, "sign-in refuses another origin")
    st, _, _ = http(base + "/api/login", "POST", json.dumps({"token": "wrong"}).encode(), {"Content-Type": "application/json"})
    check(st == 401, "sign-in refuses a wrong token")
    st, headers, _ = http(base + "/api/login", "POST", json.dumps({"token": CLIENT_TOKEN}).encode(), {"Content-Type": "application/json"})
    cookie = headers.get("Set-Cookie", "")
    check(st == 200 and "HttpOnly" in cookie and "SameSite=Strict" in cookie and CLIENT_TOKEN not in cookie,
          "sign-in sets an HttpOnly, SameSite=Strict session cookie that is not the token")
    session = cookie.split(";")[0]
    check(http(base + "/api/jobs", headers={"Cookie": session})[0] == 200, "the session cookie opens the API")
    check(http(base + "/api/jobs/" + job_id + "/file?name=../../clients.tok", headers={"Cookie": session})[0] == 404,
          "a file that is not among the job's results is not served")
    check(http(base + "/api/jobs/" + job_id + "/image?name=job.json", headers={"Cookie": session})[0] in (404, 415),
          "the image route serves images only")
    st, headers, _ = http(base + "/")
    check(st == 200 and "script-src 'self'" in headers.get("Content-Security-Policy", ""), "the page is served with a CSP")
    port = base.rsplit(":", 1)[1]
    check(http(base + "/api/session", headers={"Host": "rebound.example:" + port})[0] == 421,
          "a request naming another host is refused (DNS rebinding)")
    check(http(base + "/api/login", "POST", b"x" * 200000, {"Content-Type": "application/json"})[0] == 413,
          "a sign-in body beyond 64 KiB is refused")
    host, hport = base.split("//")[1].split(":")
    for headers, want, what in ((("Transfer-Encoding", "chunked"),), 415, "a chunked body is refused before it is read"), \
                               ((), 411, "a body without a Content-Length is refused"):
        c = httpclient.HTTPConnection(host, int(hport), timeout=20)
        c.putrequest("POST", "/api/login")
        c.putheader("Content-Type", "application/json")
        for k, v in headers:
            c.putheader(k, v)
        c.endheaders()
        check(c.getresponse().status == want, what)
        c.close()
    st, _, body = http(base + "/chart.min.js")
    check(st == 200 and b"Chart.js" in body[:200], "Chart.js is served from the binary")

    # ---- in the browser
    b = Browser()
    t0 = time.time()
    b.navigate(url)
    b.wait("!!document.getElementById('signin')", "the sign-in form")
    check(b.eval("document.querySelectorAll('main table').length") == 0, "before sign-in the page shows no data")
    b.screenshot("signin.png")
    b.eval("document.getElementById('token').value = 'not-a-token'; document.querySelector('#signin button').click(); true")
    b.wait("document.getElementById('signin-error') && document.getElementById('signin-error').textContent.includes('Refused')",
           "a wrong token refused")
    check(b.eval("fetch('/api/jobs').then(r => r.status)") == 401, "after a wrong token the page still cannot read the API")
    b.eval(f"document.getElementById('token').value = {json.dumps(CLIENT_TOKEN)}; document.querySelector('#signin button').click(); true")
    b.wait(f"!!document.querySelector('#jobs-body tr[data-job=\"{job_id}\"]')", "the job list with the job")
    check(CLIENT_TOKEN not in b.eval("document.cookie + location.href"), "the token is in no cookie the page can read and not in the URL")
    name_cell = b.eval(f"document.querySelector('#jobs-body tr[data-job=\"{job_id}\"] td.name').textContent")
    check(name_cell == NAME, "the job's name, markup and all, is shown as text")
    check(b.eval("window.__xss === undefined && document.querySelectorAll('main script, main img[src=x]').length === 0"),
          "the name's <script> and onerror did not run")
    check(b.eval(f"document.querySelector('#jobs-body tr[data-job=\"{job_id}\"]').textContent.includes('alice')"),
          "the list says who submitted the job")

    b.navigate(url + "#/job/" + job_id)
    b.wait("document.getElementById('chart-time') && +document.getElementById('chart-time').dataset.points > 0", "chart points")
    first_points = b.eval("+document.getElementById('chart-time').dataset.points")
    b.wait("(() => { const i = document.getElementById('snapshot-view0'); return i && i.complete && i.naturalWidth > 0; })()",
           "the snapshot image", timeout=120)
    b.wait("(() => { const i = document.getElementById('target-view0'); return i && i.complete && i.naturalWidth > 0; })()",
           "the target image", timeout=120)
    b.wait("document.getElementById('diff-view0').dataset.ready === '1'", "the difference image")
    # HDR views (issue 61): the exposure is set from the target's percentiles, the target and the
    # snapshot are converted from their EXRs at it, and moving the control reloads both and redraws
    # their difference at the new exposure.
    b.wait("document.getElementById('exposure-value').textContent.includes('auto')", "the automatic exposure")
    auto_ev = float(b.eval("document.getElementById('exposure').value"))
    check(auto_ev < -2, f"the automatic exposure darkens oxalis's spot-lit target ({auto_ev} stops)")
    check(b.eval("(() => { const s = document.getElementById('target-view0').getAttribute('src'); "
                 "return s.includes('.exr') && s.includes('exposure='); })()"), "the target is shown from its EXR at that exposure")
    before = b.eval("document.getElementById('diff-view0').toDataURL()")
    b.eval("(() => { const e = document.getElementById('exposure'); e.value = '0'; e.dispatchEvent(new Event('input')); return true; })()")
    b.wait("(() => { const t = document.getElementById('target-view0'), s = document.getElementById('snapshot-view0'); "
           "return t.dataset.exposure === '0' && s.dataset.exposure === '0' && !t.getAttribute('src').includes('exposure=') && t.complete; })()",
           "the views at 0 stops")
    b.wait(f"document.getElementById('diff-view0').toDataURL() !== {json.dumps(before)}", "the difference redrawn at the new exposure")
    check(b.eval("document.getElementById('exposure-value').textContent") == "0 stops", "the control shows the user's exposure")
    b.eval("document.getElementById('exposure-auto').click(); true")
    b.wait(f"document.getElementById('exposure').value === '{auto_ev:g}'", "the automatic exposure again")
    first_step = int(b.eval("document.getElementById('snapshot-view0').dataset.step"))
    b.wait(f"+document.getElementById('chart-time').dataset.points > {first_points}", "more chart points (live update)")
    b.wait(f"+document.getElementById('snapshot-view0').dataset.step > {first_step}", "a later snapshot (live update)", timeout=120)
    check(True, f"the chart grew past {first_points} points and the snapshot moved on from step {first_step}")
    check(b.eval("document.getElementById('job-title').textContent.includes('<script>') && window.__xss === undefined"),
          "the job page shows the name as text too")
    check(b.eval("document.querySelectorAll('#parameters-body tr').length > 0"), "the parameters table is filled")
    b.screenshot("job-escaped-name.png")

    b.navigate(url + "#/workers")
    b.wait("document.querySelectorAll('#workers-body tr').length >= 1", "the workers table")
    check(b.eval("document.getElementById('workers-body').textContent.includes('worker-1')"), "the workers page lists the worker")
    check(b.eval(f"[...document.querySelectorAll('#workers-body tr td:nth-child(5) a')].map(a => a.textContent).join() === '{job_id}'"),
          "the worker's jobs link to the job")
    b.screenshot("workers.png")
    b.navigate(url + "#/")  # the list again, now with a rate and an ETA
    b.wait(f"document.querySelector('#jobs-body tr[data-job=\"{job_id}\"]') && "
           f"document.querySelector('#jobs-body tr[data-job=\"{job_id}\"]').textContent.includes('/s')", "the job's rate")
    b.screenshot("jobs-running.png")

    invr("cancel", job_id, "--server", grpc_addr)

    # A zoo job as the zoo gives it, run to its end with snapshots, for docs/dashboard.md's job
    # page: its HDR views at the automatic exposure, its texture beside the truth (truth/ among the
    # results of a synthetic job).
    clean = json.loads(invr("example", "oxalis"))
    clean.setdefault("optimization", {})["steps"] = 60
    clean["optimization"]["snapshot_every"] = 10
    clean_file = os.path.join(work, "oxalis.json")
    json.dump(clean, open(clean_file, "w"))
    clean_id = submit(grpc_addr, clean_file)
    deadline = time.time() + 240
    while api(url, "/api/jobs/" + clean_id)["state"] in ("QUEUED", "RUNNING"):
        check(time.time() < deadline, "the oxalis job ends within 240 s")
        time.sleep(1)
    check(api(url, "/api/jobs/" + clean_id)["state"] == "SUCCEEDED", "the oxalis job succeeded")
    b.navigate(url + "#/job/" + clean_id)
    b.wait("(() => { const i = document.getElementById('snapshot-view0'); return i && i.complete && i.naturalWidth > 0 && "
           "document.getElementById('diff-view0').dataset.ready === '1'; })()", "the oxalis job's final render and difference", timeout=60)
    b.wait("document.querySelectorAll('#textures img').length === 2 && [...document.querySelectorAll('#textures img')].every(i => i.complete && i.naturalWidth > 0)",
           "the texture and its truth", timeout=60)
    captions = b.eval("[...document.querySelectorAll('#textures figcaption')].map(c => c.textContent).join('|')")
    check(captions == "materials/painting/albedo (truth)|materials/painting/albedo (result)",
          f"the texture is captioned by its parameter, beside its truth ({captions})")
    check(b.eval("document.getElementById('exposure-value').textContent.includes('auto')"), "the finished job's views are at the automatic exposure")
    b.screenshot("job.png")
    b.navigate(url + "#/")
    b.wait(f"!!document.querySelector('#jobs-body tr[data-job=\"{clean_id}\"]')", "the job list with the oxalis job")
    b.screenshot("jobs.png")
    log = open(os.path.join(work, "server.log"), errors="replace").read()
    check(CLIENT_TOKEN not in log and WORKER_TOKEN not in log, "no token in the server's log")
    check("dashboard: alice signed in" in log, "the sign-in is logged by name")
    print(f"dashboard: browser part took {time.time() - t0:.1f} s")

    tls_checks()
    if MEASURE:
        measure(b)
    print("dashboard: all checks passed")


def tls_checks():
    """Beyond loopback: refused without TLS (or without client tokens); over HTTPS it works and the
    cookie is Secure."""
    store = os.path.join(work, "tls-store")
    r = subprocess.run([os.path.join(BIN, "invr-server"), "--store", store, "--address", "127.0.0.1:0", "--http-address", "0.0.0.0:0"],
                       capture_output=True, text=True, timeout=30)
    check(r.returncode != 0 and "it needs TLS (--tls-cert and --tls-key) or --insecure" in r.stderr,
          "a plain-HTTP dashboard beyond loopback is refused, naming the fix")
    os.chdir(work)
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", "dash.key", "-out", "dash.pem", "-days", "2",
                    "-subj", "/CN=localhost", "-addext", "subjectAltName=DNS:localhost,IP:127.0.0.1"], check=True, capture_output=True)
    r = subprocess.run([os.path.join(BIN, "invr-server"), "--store", store, "--address", "127.0.0.1:0", "--http-address", "0.0.0.0:0",
                        "--tls-cert", "dash.pem", "--tls-key", "dash.key"], capture_output=True, text=True, timeout=30)
    check(r.returncode != 0 and "it needs client tokens (--client-token-file) or --insecure" in r.stderr,
          "an HTTPS dashboard beyond loopback without client tokens is refused")
    _, _, url = start_server("tls", ["--tls-cert", "dash.pem", "--tls-key", "dash.key"], http="0.0.0.0:0")
    check(url.startswith("https://"), "with a certificate the dashboard is served over HTTPS")
    import ssl
    ctx = ssl.create_default_context(cafile=os.path.join(work, "dash.pem"))
    port = url.rsplit(":", 1)[1].strip("/")
    base = "https://127.0.0.1:" + port
    with urllib.request.urlopen(base + "/api/session", context=ctx, timeout=20) as r:
        check(r.status == 200 and json.loads(r.read())["auth_required"], "HTTPS answers, and asks for a token")
    req = urllib.request.Request(base + "/api/login", data=json.dumps({"token": CLIENT_TOKEN}).encode(), method="POST",
                                 headers={"Content-Type": "application/json"})
    with urllib.request.urlopen(req, context=ctx, timeout=20) as r:
        check("; Secure" in r.headers.get("Set-Cookie", ""), "over HTTPS the session cookie is Secure")
    try:
        urllib.request.urlopen("http://127.0.0.1:" + port + "/api/session", timeout=5)
        fail("plain HTTP was answered on the HTTPS port")
    except (urllib.error.URLError, ConnectionError, OSError):
        check(True, "plain HTTP gets nothing on the HTTPS port")


def sign_in(b):
    b.wait("!!document.getElementById('signin')", "the sign-in form")
    b.eval(f"document.getElementById('token').value = {json.dumps(CLIENT_TOKEN)}; document.querySelector('#signin button').click(); true")
    b.wait("!!document.getElementById('jobs-body')", "the job list after sign-in")


def rss_kb(pid):
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return 0


def measure(b):
    # 1. The job list with 100 jobs: no worker, so they stay queued.
    p, grpc_addr, url = start_server("hundred", ["--max-queued", "200"])
    job = json.loads(invr("example", "oxalis"))
    job_file = os.path.join(work, "small.json")
    json.dump(job, open(job_file, "w"))
    for i in range(100):
        submit(grpc_addr, job_file)
    b.navigate(url)
    sign_in(b)
    b.navigate("about:blank")
    times = []
    for _ in range(5):
        b.navigate(url)
        b.wait("document.querySelectorAll('#jobs-body tr').length === 100", "100 rows")
        times.append(b.eval("performance.getEntriesByName('invr-jobs-drawn')[0].startTime"))
    print(f"measure: job list with 100 jobs: 100 rows drawn {min(times):.0f} ms after navigation start (median "
          f"{sorted(times)[len(times) // 2]:.0f} ms, max {max(times):.0f} ms of 5 loads)")
    p.kill()

    # 2. Memory over a 3000-step job, watched and unwatched: the server's RSS every 500 steps while
    # it runs (the final renders at the end take memory of their own, so the end is apart).
    for watched in (False, True):
        tag = "watched" if watched else "unwatched"
        p, grpc_addr, url = start_server(tag)
        w = start_worker(grpc_addr, tag + "-worker")
        job = json.loads(invr("example", "oxalis"))
        job["optimization"]["steps"] = 3000
        job["optimization"]["snapshot_every"] = 100
        jf = os.path.join(work, tag + ".json")
        json.dump(job, open(jf, "w"))
        jid = submit(grpc_addr, jf)
        if watched:
            b.navigate(url)
            sign_in(b)
            b.navigate(url + "#/job/" + jid)
        marks = {}
        t0 = time.time()
        while True:
            st = api(url, "/api/jobs/" + jid)
            if st["state"] not in ("QUEUED", "RUNNING"):
                break
            marks.setdefault(st["step"] // 500 * 500, rss_kb(p.pid))
            time.sleep(1)
        marks.pop(0, None)
        ks = sorted(marks)
        print(f"measure: {tag}: 3000 steps in {time.time() - t0:.0f} s; server RSS while running: " +
              ", ".join(f"step {k}: {marks[k] / 1024:.1f} MiB" for k in ks) +
              f"; growth from step {ks[0]} to {ks[-1]}: {(marks[ks[-1]] - marks[ks[0]]) / 1024:.1f} MiB; after the final renders "
              f"{rss_kb(p.pid) / 1024:.1f} MiB")
        b.navigate("about:blank")
        p.kill()
        w.kill()


if __name__ == "__main__":
    try:
        main()
    finally:
        cleanup()
