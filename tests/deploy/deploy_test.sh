#!/usr/bin/env bash
# Static checks of the deployment files under deploy/ (no Docker daemon, no cluster, no
# build needed; a few seconds):
#   - every YAML file under deploy/ parses (python3 + PyYAML, Debian package python3-yaml);
#   - docker-compose files: services with an image or a build whose Dockerfile exists, a
#     coordinator and a scalable worker (no container_name, no published ports) that gets
#     CPVS_TOKEN, secrets and volumes that services use are declared;
#   - Kubernetes manifests: every document has apiVersion, kind and metadata.name; the
#     kustomization lists only files that exist (and every manifest of the folder);
#     selectors, Services, volumes, Secret references and the HPA's target resolve;
#     containers have resource requests and limits;
#   - the Dockerfile has FROM stages, runs deploy/setup.sh, copies only what exists, and
#     ends in a non-root stage with CMD and EXPOSE;
#   - deploy/*.sh parse (bash -n); make-secrets.sh makes consistent tokens (and, with
#     openssl, a certificate that verifies against its CA);
#   - every kustomization renders with `kubectl kustomize` and its objects are checked
#     (kinds, images, probes, resources); a missing kubectl fails the test.
# Exits 0 when all pass, 1 (naming every failure) otherwise.
set -euo pipefail

ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
DEPLOY="$ROOT/deploy"
LIMIT="${DEPLOY_TEST_TIMEOUT:-60}"   # seconds per step
failures=0

fail() { echo "FAIL: $*" >&2; failures=$((failures + 1)); }
ok() { echo "ok:   $*"; }

[ -d "$DEPLOY" ] || { echo "FAIL: no deploy/ folder at $DEPLOY" >&2; exit 1; }

# A python3 with PyYAML: the one on PATH, else Debian's.
PY=""
for cand in python3 /usr/bin/python3; do
  if command -v "$cand" >/dev/null 2>&1 && timeout 20 "$cand" -c 'import yaml' 2>/dev/null; then
    PY="$cand"; break
  fi
done
if [ -z "$PY" ]; then
  echo "FAIL: deploy_test needs python3 with the yaml module (Debian: apt-get install python3-yaml)" >&2
  exit 1
fi

# ---------------------------------------------------------------------------------------
# YAML, compose, Kubernetes and Dockerfile checks.
if ! timeout "$LIMIT" "$PY" - "$ROOT" <<'PY'
import os, re, sys
import yaml

root = sys.argv[1]
deploy = os.path.join(root, "deploy")
failures = []

def fail(msg):
    failures.append(msg)
    print("FAIL: " + msg, file=sys.stderr)

def ok(msg):
    print("ok:   " + msg)

def rel(p):
    return os.path.relpath(p, root)

# --- every YAML file parses ------------------------------------------------------------
yaml_files = []
for dirpath, dirnames, filenames in os.walk(deploy):
    dirnames[:] = sorted(d for d in dirnames if d != "secrets")   # generated, never checked in
    for f in sorted(filenames):
        if f.endswith((".yml", ".yaml")):
            yaml_files.append(os.path.join(dirpath, f))
if not yaml_files:
    fail("no YAML files under deploy/")

docs_by_file = {}
for path in yaml_files:
    try:
        with open(path, encoding="utf-8") as fh:
            docs = [d for d in yaml.safe_load_all(fh) if d is not None]
    except yaml.YAMLError as e:
        fail("%s does not parse as YAML: %s" % (rel(path), e))
        continue
    if not docs:
        fail("%s holds no YAML document" % rel(path))
        continue
    if not all(isinstance(d, dict) for d in docs):
        fail("%s: every document must be a mapping" % rel(path))
        continue
    docs_by_file[path] = docs
    ok("%s parses (%d document%s)" % (rel(path), len(docs), "" if len(docs) == 1 else "s"))

# --- docker compose --------------------------------------------------------------------
compose_files = sorted(p for p in docs_by_file
                       if os.path.dirname(p) == deploy and re.match(r"(docker-)?compose.*\.ya?ml$", os.path.basename(p)))
base = os.path.join(deploy, "docker-compose.yml")
if base not in docs_by_file:
    fail("deploy/docker-compose.yml is missing or does not parse")
else:
    merged_secrets, merged_volumes = set(), set()
    for p in compose_files:
        d = docs_by_file[p][0]
        merged_secrets |= set((d.get("secrets") or {}).keys())
        merged_volumes |= set((d.get("volumes") or {}).keys())
    for p in compose_files:
        d = docs_by_file[p][0]
        services = d.get("services")
        if not isinstance(services, dict) or not services:
            fail("%s: no services" % rel(p)); continue
        for name, svc in services.items():
            svc = svc or {}
            if p == base and not (svc.get("image") or svc.get("build")):
                fail("%s: service %s has neither image nor build" % (rel(p), name))
            build = svc.get("build")
            if isinstance(build, dict):
                ctx = os.path.normpath(os.path.join(deploy, build.get("context", ".")))
                df = os.path.join(ctx, build.get("dockerfile", "Dockerfile"))
                if not os.path.isfile(df):
                    fail("%s: service %s builds with %s, which does not exist" % (rel(p), name, rel(df)))
            for s in svc.get("secrets") or []:
                sname = s if isinstance(s, str) else (s or {}).get("source")
                if sname not in merged_secrets:
                    fail("%s: service %s uses secret %s, declared nowhere" % (rel(p), name, sname))
            for v in svc.get("volumes") or []:
                src = v.split(":")[0] if isinstance(v, str) else (v or {}).get("source", "")
                if src and not src.startswith((".", "/", "$", "~")) and src not in merged_volumes:
                    fail("%s: service %s mounts volume %s, declared nowhere" % (rel(p), name, src))
        ok("%s: services %s" % (rel(p), ", ".join(sorted(services))))
    services = docs_by_file[base][0].get("services") or {}
    coord, worker = services.get("coordinator"), services.get("worker")
    if not coord:
        fail("docker-compose.yml: no coordinator service")
    else:
        cmd = coord.get("command") or []
        cmd = cmd.split() if isinstance(cmd, str) else [str(c) for c in cmd]
        if "--tokens" not in cmd:
            fail("docker-compose.yml: the coordinator runs without --tokens")
        if not any("7443" in str(port) for port in coord.get("ports") or []):
            fail("docker-compose.yml: the coordinator does not publish port 7443")
        if not any(str(v).endswith(":/var/lib/cpvs") for v in coord.get("volumes") or []):
            fail("docker-compose.yml: the coordinator's --data folder /var/lib/cpvs is not on a volume")
        # R7: cleartext tokens on compose's network are said in words, and the port is then
        # published on the host's loopback only by default.
        if "--tls-cert" not in cmd and "--allow-plaintext-tokens" not in cmd:
            fail("docker-compose.yml: the coordinator takes tokens without TLS and without --allow-plaintext-tokens (it would refuse to start)")
        for port in coord.get("ports") or []:
            if "--tls-cert" not in cmd and not str(port).startswith("${CPVS_BIND:-127.0.0.1}:") and not str(port).startswith("127.0.0.1:"):
                fail("docker-compose.yml: port %s is published beyond loopback while tokens travel in cleartext" % port)
        ok("docker-compose.yml: coordinator with --tokens, port 7443 on loopback and a data volume")
    if not worker:
        fail("docker-compose.yml: no worker service")
    else:
        if "container_name" in worker or worker.get("ports"):
            fail("docker-compose.yml: worker has container_name or ports; --scale worker=N needs neither")
        env = worker.get("environment") or {}
        env_names = set(env) if isinstance(env, dict) else {e.split("=")[0] for e in env}
        env_files = worker.get("env_file") or []
        env_files = [env_files] if isinstance(env_files, (str, dict)) else env_files
        if "CPVS_TOKEN" not in env_names and not env_files:
            fail("docker-compose.yml: the worker gets no CPVS_TOKEN (environment or env_file)")
        cmd = worker.get("command") or []
        cmd = cmd.split() if isinstance(cmd, str) else [str(c) for c in cmd]
        if "--server" not in cmd or "coordinator:7443" not in cmd:
            fail("docker-compose.yml: the worker does not dial --server coordinator:7443")
        if "--ca" not in cmd and "--allow-plaintext-token" not in cmd:
            fail("docker-compose.yml: the worker sends its token without TLS and without --allow-plaintext-token (it would refuse)")
        ok("docker-compose.yml: worker scalable, dials coordinator:7443, gets CPVS_TOKEN")

# --- Kubernetes ------------------------------------------------------------------------
k8s = os.path.join(deploy, "k8s")
kust_path = os.path.join(k8s, "kustomization.yaml")
objects = []   # (file, doc)
for p, docs in sorted(docs_by_file.items()):
    if os.path.dirname(p) != k8s or p == kust_path:
        continue
    for i, d in enumerate(docs):
        where = "%s document %d" % (rel(p), i + 1)
        missing = [k for k in ("apiVersion", "kind") if not isinstance(d.get(k), str) or not d.get(k)]
        name = (d.get("metadata") or {}).get("name") if isinstance(d.get("metadata"), dict) else None
        if not isinstance(name, str) or not name:
            missing.append("metadata.name")
        if missing:
            fail("%s lacks %s" % (where, ", ".join(missing)))
            continue
        if "namespace" in d["metadata"]:
            fail("%s sets metadata.namespace; the manifests are namespace-free" % where)
        objects.append((p, d))
ok("k8s: %d objects with apiVersion, kind, metadata.name: %s" % (
    len(objects), ", ".join("%s/%s" % (d["kind"], d["metadata"]["name"]) for _, d in objects)))

if kust_path not in docs_by_file:
    fail("deploy/k8s/kustomization.yaml is missing or does not parse")
else:
    kust = docs_by_file[kust_path][0]
    if kust.get("kind") != "Kustomization":
        fail("deploy/k8s/kustomization.yaml: kind is not Kustomization")
    resources = kust.get("resources") or []
    if not resources:
        fail("deploy/k8s/kustomization.yaml lists no resources")
    for r in resources:
        if not os.path.exists(os.path.join(k8s, r)):
            fail("deploy/k8s/kustomization.yaml lists %s, which does not exist" % r)
    listed = {os.path.normpath(os.path.join(k8s, r)) for r in resources}
    for p in sorted({p for p, _ in objects}):
        if p not in listed:
            fail("%s is not listed in deploy/k8s/kustomization.yaml" % rel(p))
    ok("k8s/kustomization.yaml lists %d existing files: %s" % (len(resources), ", ".join(resources)))

by_kind = {}
for _, d in objects:
    by_kind.setdefault(d["kind"], {})[d["metadata"]["name"]] = d

secrets = by_kind.get("Secret", {})
def secret_keys(name):
    s = secrets.get(name)
    return None if s is None else set(s.get("data") or {}) | set(s.get("stringData") or {})

for name, s in secrets.items():
    if s.get("type") == "kubernetes.io/tls" and not {"tls.crt", "tls.key"} <= secret_keys(name):
        fail("Secret %s is kubernetes.io/tls without tls.crt and tls.key" % name)

workloads = {}
for kind in ("StatefulSet", "Deployment"):
    for name, w in by_kind.get(kind, {}).items():
        workloads[(kind, name)] = w
        spec = w.get("spec") or {}
        tmpl = spec.get("template") or {}
        labels = (tmpl.get("metadata") or {}).get("labels") or {}
        match = (spec.get("selector") or {}).get("matchLabels") or {}
        if not match or any(labels.get(k) != v for k, v in match.items()):
            fail("%s %s: selector.matchLabels does not match the pod template's labels" % (kind, name))
        pod = tmpl.get("spec") or {}
        vol_names = {v.get("name") for v in pod.get("volumes") or []}
        vol_names |= {(c.get("metadata") or {}).get("name") for c in spec.get("volumeClaimTemplates") or []}
        for v in pod.get("volumes") or []:
            sec = v.get("secret")
            if sec:
                keys = secret_keys(sec.get("secretName"))
                if keys is None:
                    fail("%s %s: volume %s uses Secret %s, which is not defined" % (kind, name, v.get("name"), sec.get("secretName")))
                else:
                    for item in sec.get("items") or []:
                        if item.get("key") not in keys:
                            fail("%s %s: volume %s wants key %s of Secret %s, which it lacks" % (kind, name, v.get("name"), item.get("key"), sec.get("secretName")))
        containers = pod.get("containers") or []
        if not containers:
            fail("%s %s has no containers" % (kind, name))
        for c in containers:
            cname = "%s %s container %s" % (kind, name, c.get("name"))
            if not c.get("image"):
                fail("%s has no image" % cname)
            res = c.get("resources") or {}
            for part in ("requests", "limits"):
                if not {"cpu", "memory"} <= set(res.get(part) or {}):
                    fail("%s lacks resources.%s for cpu and memory" % (cname, part))
            for m in c.get("volumeMounts") or []:
                if m.get("name") not in vol_names:
                    fail("%s mounts %s, which is no volume" % (cname, m.get("name")))
            for e in c.get("env") or []:
                ref = (e.get("valueFrom") or {}).get("secretKeyRef")
                if ref:
                    keys = secret_keys(ref.get("name"))
                    if keys is None or ref.get("key") not in keys:
                        fail("%s: env %s refers to %s/%s, which is not defined" % (cname, e.get("name"), ref.get("name"), ref.get("key")))
            port_names = {p.get("name") for p in c.get("ports") or []}
            for probe in ("readinessProbe", "livenessProbe", "startupProbe"):
                tcp = (c.get(probe) or {}).get("tcpSocket")
                if tcp and isinstance(tcp.get("port"), str) and tcp["port"] not in port_names:
                    fail("%s: %s names port %s, which the container lacks" % (cname, probe, tcp["port"]))
        ok("%s %s: selector, volumes, Secret references and resources resolve" % (kind, name))

coord = workloads.get(("StatefulSet", "cpvs-coordinator"))
if not coord:
    fail("k8s: no StatefulSet cpvs-coordinator")
else:
    spec = coord["spec"]
    if not spec.get("volumeClaimTemplates"):
        fail("StatefulSet cpvs-coordinator has no volumeClaimTemplates")
    if spec.get("serviceName") not in by_kind.get("Service", {}):
        fail("StatefulSet cpvs-coordinator: serviceName %s is no Service here" % spec.get("serviceName"))
    c = spec["template"]["spec"]["containers"][0]
    sp = (c.get("startupProbe") or {}).get("tcpSocket")
    ports = {p.get("name"): p.get("containerPort") for p in c.get("ports") or []}
    if not sp or (ports.get(sp.get("port"), sp.get("port")) != 7443):
        fail("StatefulSet cpvs-coordinator: no tcpSocket startup probe on port 7443")
    check = ((c.get("readinessProbe") or {}).get("exec") or {}).get("command") or []
    if "--check" not in check or "127.0.0.1:7443" not in check:
        fail("StatefulSet cpvs-coordinator: readiness is not `cpvs-server --check` on 127.0.0.1:7443")
    ok("StatefulSet cpvs-coordinator: volume claim template, governing Service, TCP startup on 7443, ready by --check")

services = by_kind.get("Service", {})
svc = services.get("cpvs-coordinator")
if not svc:
    fail("k8s: no Service cpvs-coordinator")
elif (svc["spec"].get("type", "ClusterIP") != "ClusterIP"
      or not any(p.get("port") == 7443 for p in svc["spec"].get("ports") or [])):
    fail("Service cpvs-coordinator is not ClusterIP on port 7443")
for name, s in services.items():
    sel = (s.get("spec") or {}).get("selector") or {}
    if not any(all(((w["spec"]["template"].get("metadata") or {}).get("labels") or {}).get(k) == v
                   for k, v in sel.items()) for w in workloads.values()):
        fail("Service %s selects no pod template" % name)
ok("Services %s select pods" % ", ".join(sorted(services)))

hpas = by_kind.get("HorizontalPodAutoscaler", {})
if not hpas:
    fail("k8s: no HorizontalPodAutoscaler")
for name, h in hpas.items():
    if h["apiVersion"] != "autoscaling/v2":
        fail("HorizontalPodAutoscaler %s is %s, not autoscaling/v2" % (name, h["apiVersion"]))
    t = h["spec"].get("scaleTargetRef") or {}
    if (t.get("kind"), t.get("name")) not in workloads:
        fail("HorizontalPodAutoscaler %s targets %s %s, which is not defined" % (name, t.get("kind"), t.get("name")))
    external = [((m.get("external") or {}).get("metric") or {}).get("name") for m in h["spec"].get("metrics") or []
                if m.get("type") == "External"]
    if "cpvs_tiles_outstanding" not in external:
        fail("HorizontalPodAutoscaler %s does not follow the outstanding tiles (External cpvs_tiles_outstanding)" % name)
    if any(m.get("type") == "Resource" for m in h["spec"].get("metrics") or []):
        fail("HorizontalPodAutoscaler %s also scales on a resource: a baking worker is always busy" % name)
    ok("HorizontalPodAutoscaler %s: autoscaling/v2 on cpvs_tiles_outstanding, targets %s %s" % (name, t.get("kind"), t.get("name")))

# --- monitoring: alerts, dashboard and the adapter's rule name only metrics that exist --
# The metric families the programs register (prometheus-cpp's .Name("...")), with the
# series a histogram adds; the dashboard, the alerts and the autoscaler must use no other.
families, histograms = set(), set()
for src in ("server/coordinator/farm_metrics.cpp", "worker/worker_metrics.cpp", "metrics/src/process.cpp"):
    text = open(os.path.join(root, src), encoding="utf-8").read()
    for m in re.finditer(r'Build(Counter|Gauge|Histogram)\(\)\s*\.Name\("([a-z_]+)"\)', text):
        families.add(m.group(2))
        if m.group(1) == "Histogram":
            histograms.add(m.group(2))
    for m in re.finditer(r'\b(gauge|counter|histogram)\(\s*\*?\w+,\s*"([a-z_]+)"', text):
        families.add(m.group(2))
        if m.group(1) == "histogram":
            histograms.add(m.group(2))
known = families | {h + s for h in histograms for s in ("_bucket", "_sum", "_count")} | {"up"}
promql_words = {"sum", "by", "rate", "increase", "delta", "histogram_quantile", "max", "min", "avg", "count", "and",
                "or", "unless", "le", "on", "without", "ignoring", "offset", "bool"}
def metrics_of(expr):
    expr = re.sub(r'\{[^}]*\}', '', expr)          # label matchers
    expr = re.sub(r'\[[^\]]*\]', '', expr)         # ranges
    expr = re.sub(r'\(([a-z_, ]+)\)', lambda m: "" if all(w.strip() in promql_words or not w.strip() or
                                                         w.strip() in ("state", "event", "stage", "kind", "job", "outcome", "le")
                                                         for w in m.group(1).split(",")) else m.group(0), expr)
    return {w for w in re.findall(r'[a-z_][a-z0-9_]*', expr) if w not in promql_words and not w.startswith("__")}
monitoring = os.path.join(deploy, "monitoring")
if len(families) < 20:
    fail("monitoring: found only %d metric families in the sources (%s)" % (len(families), ", ".join(sorted(families))))
alerts_path = os.path.join(monitoring, "alerts.yaml")
if not os.path.isfile(alerts_path):
    fail("deploy/monitoring/alerts.yaml is missing")
else:
    rules = [r for g in yaml.safe_load(open(alerts_path, encoding="utf-8"))["groups"] for r in g["rules"]]
    for r in rules:
        where = "alert %s" % r.get("alert")
        if not r.get("alert") or not r.get("expr"):
            fail("deploy/monitoring/alerts.yaml: a rule without alert or expr")
        if (r.get("labels") or {}).get("severity") not in ("warning", "critical"):
            fail("%s: severity is not warning or critical" % where)
        if not (r.get("annotations") or {}).get("summary") or not (r.get("annotations") or {}).get("description"):
            fail("%s: no summary or description" % where)
        unknown = metrics_of(str(r.get("expr"))) - known
        if unknown:
            fail("%s names metrics no program exports: %s" % (where, ", ".join(sorted(unknown))))
    ok("deploy/monitoring/alerts.yaml: %d alerts on exported metrics" % len(rules))
dashboard_path = os.path.join(monitoring, "grafana-dashboard.json")
try:
    import json
    dashboard = json.load(open(dashboard_path, encoding="utf-8"))
    exprs = [t["expr"] for p in dashboard["panels"] for t in p.get("targets") or []]
    if not dashboard.get("uid") or not dashboard.get("title") or len(dashboard["panels"]) < 8:
        fail("grafana-dashboard.json: no uid, title, or fewer than 8 panels")
    used = set()
    for p in dashboard["panels"]:
        if not p.get("title") or not p.get("targets"):
            fail("grafana-dashboard.json: panel %s has no title or no query" % p.get("id"))
    for e in exprs:
        used |= metrics_of(e)
        unknown = metrics_of(e) - known
        if unknown:
            fail("grafana-dashboard.json: %r names metrics no program exports: %s" % (e, ", ".join(sorted(unknown))))
    for must in ("cpvs_tiles_outstanding", "cpvs_leases_total", "cpvs_merge_backlog", "cpvs_track_keyframe_lag",
                 "cpvs_store_bytes", "process_resident_memory_bytes", "process_open_fds"):
        if must not in used:
            fail("grafana-dashboard.json shows no %s" % must)
    ok("deploy/monitoring/grafana-dashboard.json: %d panels, %d queries on exported metrics" % (len(dashboard["panels"]), len(exprs)))
except (OSError, ValueError, KeyError) as e:
    fail("deploy/monitoring/grafana-dashboard.json: %s" % e)
adapter_path = os.path.join(monitoring, "prometheus-adapter-rules.yaml")
if os.path.isfile(adapter_path):
    served = {r["name"]["as"] for r in yaml.safe_load(open(adapter_path, encoding="utf-8"))["externalRules"]}
    for name, h in hpas.items():
        for m in h["spec"].get("metrics") or []:
            metric = ((m.get("external") or {}).get("metric") or {}).get("name")
            if m.get("type") == "External" and metric not in served:
                fail("HorizontalPodAutoscaler %s follows %s, which the adapter's rules do not serve" % (name, metric))
            if m.get("type") == "External" and metric not in families:
                fail("HorizontalPodAutoscaler %s follows %s, which the coordinator does not export" % (name, metric))
    ok("the HPA's external metric is served by deploy/monitoring/prometheus-adapter-rules.yaml")
else:
    fail("deploy/monitoring/prometheus-adapter-rules.yaml is missing")

# --- Dockerfile ------------------------------------------------------------------------
dockerfile = os.path.join(deploy, "Dockerfile")
if not os.path.isfile(dockerfile):
    fail("deploy/Dockerfile is missing")
else:
    text = open(dockerfile, encoding="utf-8").read()
    lines = re.sub(r"\\\n", " ", text).splitlines()           # join continuation lines
    lines = [l.strip() for l in lines if l.strip() and not l.strip().startswith("#")]
    stages, current, final = [], None, {}
    for l in lines:
        word, _, rest = l.partition(" ")
        word = word.upper()
        if word == "FROM":
            m = re.match(r"(?:--platform=\S+\s+)?(\S+)(?:\s+AS\s+(\S+))?\s*$", rest.strip(), re.I)
            if not m:
                fail("Dockerfile: cannot read '%s'" % l); continue
            current = (m.group(2) or str(len(stages))).lower()
            stages.append(current)
            final = {}
        elif word == "COPY" and current is not None:
            args = rest.split()
            frm = [a.split("=", 1)[1] for a in args if a.startswith("--from=")]
            if frm:
                if frm[0].lower() not in stages[:-1]:
                    fail("Dockerfile: COPY --from=%s names no earlier stage" % frm[0])
            else:
                srcs = [a for a in args if not a.startswith("--")][:-1]
                for s in srcs:
                    if not os.path.exists(os.path.join(root, s)):
                        fail("Dockerfile: COPY %s: no such path in the repository" % s)
        final[word] = rest.strip()
    if len(stages) < 2:
        fail("Dockerfile: %d FROM stage(s); a build and a runtime stage are expected" % len(stages))
    if "deploy/setup.sh" not in text:
        fail("Dockerfile does not reference deploy/setup.sh")
    if "cmake --install" not in text:
        fail("Dockerfile does not install the build (cmake --install)")
    for b in ("bin/cpvs-server", "bin/cpvs-worker", "bin/cpvs"):
        if b not in text:
            fail("Dockerfile does not check that it installed %s" % b)
    user = final.get("USER", "")
    if not user or user.split(":")[0] in ("root", "0"):
        fail("Dockerfile: the final stage does not switch to a non-root USER")
    if "CMD" not in final:
        fail("Dockerfile: the final stage has no CMD")
    else:
        # R7: the image's default command is no open farm and takes no cleartext tokens.
        cmd = final["CMD"]
        if "--tokens" not in cmd and "127.0.0.1" not in cmd:
            fail("Dockerfile: CMD serves beyond loopback without --tokens: an open farm")
        if "--tokens" in cmd and "--tls-cert" not in cmd and "127.0.0.1" not in cmd:
            fail("Dockerfile: CMD takes tokens in cleartext beyond loopback")
    if "7443" not in final.get("EXPOSE", ""):
        fail("Dockerfile: the final stage does not EXPOSE 7443")
    ok("Dockerfile: stages %s, runs deploy/setup.sh, final stage USER %s, EXPOSE %s, CMD %s" % (
        ", ".join(stages), user, final.get("EXPOSE"), final.get("CMD")))
    ignore = os.path.join(deploy, "Dockerfile.dockerignore")
    if os.path.isfile(ignore):
        pats = [l.strip() for l in open(ignore, encoding="utf-8") if l.strip() and not l.startswith("#")]
        for bad in ("deploy", "deploy/setup.sh", "*.sh", "*", "CMakeLists.txt", "core"):
            if bad in pats:
                fail("Dockerfile.dockerignore excludes %s, which the build needs" % bad)
        ok("Dockerfile.dockerignore keeps the sources (%s)" % ", ".join(pats))

sys.exit(1 if failures else 0)
PY
then
  fail "YAML/compose/Kubernetes/Dockerfile checks (see above)"
fi

# ---------------------------------------------------------------------------------------
# Shell scripts parse; make-secrets.sh makes consistent secrets.
for s in "$DEPLOY"/*.sh; do
  if bash -n "$s"; then ok "bash -n ${s#"$ROOT"/}"; else fail "${s#"$ROOT"/} does not parse"; fi
done

if [ -f "$DEPLOY/make-secrets.sh" ]; then
  tmp="$(mktemp -d)"
  trap 'rm -rf "$tmp"' EXIT
  tls_args=()
  if command -v openssl >/dev/null; then tls_args=(--tls "farm.example.com,10.1.2.3" --days 2); fi
  if ! timeout "$LIMIT" bash "$DEPLOY/make-secrets.sh" --dir "$tmp/s" "${tls_args[@]}" >"$tmp/log" 2>&1; then
    fail "make-secrets.sh failed: $(cat "$tmp/log")"
  else
    roles="$(awk '{print $1}' "$tmp/s/tokens" | sort | tr '\n' ' ')"
    worker_token="$(awk '$1 == "worker" {print $2}' "$tmp/s/tokens")"
    metrics_token="$(awk '$1 == "metrics" {print $2}' "$tmp/s/tokens")"
    if [ "$roles" != "admin client metrics worker " ] || [ "$(awk 'NF != 2' "$tmp/s/tokens")" != "" ]; then
      fail "make-secrets.sh: tokens file is not four lines 'ROLE TOKEN' for admin, client, metrics, worker"
    elif [ "$(cat "$tmp/s/worker.env")" != "CPVS_TOKEN=$worker_token" ] \
         || [ "$(cat "$tmp/s/worker.token")" != "$worker_token" ]; then
      fail "make-secrets.sh: worker.env/worker.token do not hold the tokens file's worker token"
    elif [ "$(cat "$tmp/s/metrics.token")" != "$metrics_token" ]; then
      fail "make-secrets.sh: metrics.token does not hold the tokens file's metrics token"
    elif [ "$(sort -u <(awk '{print $2}' "$tmp/s/tokens") | wc -l)" -ne 4 ]; then
      fail "make-secrets.sh: the four tokens are not distinct"
    else
      ok "make-secrets.sh: tokens for admin, client, metrics, worker; worker.env and metrics.token match"
    fi
    if [ ${#tls_args[@]} -gt 0 ]; then
      if timeout "$LIMIT" openssl verify -CAfile "$tmp/s/ca.crt" "$tmp/s/tls.crt" >/dev/null 2>&1 \
         && openssl x509 -in "$tmp/s/tls.crt" -noout -text | grep 'DNS:cpvs-coordinator' >/dev/null \
         && openssl x509 -in "$tmp/s/tls.crt" -noout -text | grep 'IP Address:10.1.2.3' >/dev/null; then
        ok "make-secrets.sh --tls: certificate verifies against ca.crt and names cpvs-coordinator, 10.1.2.3"
      else
        fail "make-secrets.sh --tls: certificate does not verify or lacks its names"
      fi
    fi
  fi
fi

# ---------------------------------------------------------------------------------------
# Every kustomization renders (`kubectl kustomize` works offline), and the rendered objects
# are the farm: kinds, the kustomization's image on every container, probes on named
# ports, resources, the HPA's target.
if ! command -v kubectl >/dev/null 2>&1; then
  fail "kubectl is not installed (deploy/setup.sh installs Debian's kubernetes-client when no kubectl is there)"
else
  kustomizations="$(find "$DEPLOY" -name kustomization.yaml -not -path '*/secrets/*' | sort)"
  [ -n "$kustomizations" ] || fail "no kustomization.yaml under deploy/"
  for k in $kustomizations; do
    dir="$(dirname "$k")"
    rendered="$(mktemp)"
    if ! timeout "$LIMIT" kubectl kustomize "$dir" >"$rendered" 2>&1; then
      fail "kubectl kustomize ${dir#"$ROOT"/}: $(cat "$rendered")"
    elif timeout "$LIMIT" "$PY" - "$k" "$rendered" <<'PY'
import re, sys
import yaml

kust_path, rendered_path = sys.argv[1], sys.argv[2]
kust = yaml.safe_load(open(kust_path, encoding="utf-8"))
docs = [d for d in yaml.safe_load_all(open(rendered_path, encoding="utf-8")) if d]
failures = []
def fail(msg):
    failures.append(msg)
    print("FAIL: rendered %s: %s" % (kust_path, msg), file=sys.stderr)

counts = {}
for d in docs:
    counts[d.get("kind")] = counts.get(d.get("kind"), 0) + 1
want = {"Secret": 2, "Service": 2, "StatefulSet": 1, "Deployment": 1, "HorizontalPodAutoscaler": 1}
for kind, n in want.items():
    if counts.get(kind, 0) != n:
        fail("%d %s object(s), %d expected" % (counts.get(kind, 0), kind, n))

images = {}
for i in kust.get("images") or []:
    images[i["name"]] = "%s:%s" % (i.get("newName", i["name"]), i.get("newTag", "latest"))

def quantity(q, cpu):
    m = re.fullmatch(r"([0-9.]+)(m|Ki|Mi|Gi|Ti|k|M|G|T)?", str(q))
    if not m:
        return None
    scale = {None: 1, "m": 1e-3, "Ki": 2**10, "Mi": 2**20, "Gi": 2**30, "Ti": 2**40,
             "k": 1e3, "M": 1e6, "G": 1e9, "T": 1e12}[m.group(2)]
    return float(m.group(1)) * scale

workloads = {(d["kind"], d["metadata"]["name"]): d for d in docs if d.get("kind") in ("StatefulSet", "Deployment")}
for (kind, name), w in sorted(workloads.items()):
    for c in w["spec"]["template"]["spec"].get("containers") or []:
        where = "%s %s container %s" % (kind, name, c.get("name"))
        image = c.get("image", "")
        if image not in images.values():
            fail("%s runs image %r, not the kustomization's %s" % (where, image, ", ".join(images.values())))
        res = c.get("resources") or {}
        for key in ("cpu", "memory"):
            req = quantity((res.get("requests") or {}).get(key), key == "cpu")
            lim = quantity((res.get("limits") or {}).get(key), key == "cpu")
            if req is None or lim is None:
                fail("%s: resources.requests/limits.%s missing or unreadable" % (where, key))
            elif req > lim:
                fail("%s: requests.%s above limits.%s" % (where, key, key))
        ports = {p.get("name"): p.get("containerPort") for p in c.get("ports") or []}
        for probe in ("startupProbe", "readinessProbe", "livenessProbe"):
            p = c.get(probe)
            if p is None:
                if name == "cpvs-coordinator":
                    fail("%s has no %s" % (where, probe))
                continue
            port = (p.get("tcpSocket") or p.get("grpc") or p.get("httpGet") or {}).get("port")
            if isinstance(port, str) and port not in ports:
                fail("%s: %s on port %s, which the container does not name" % (where, probe, port))
            if port is None and "exec" not in p:
                fail("%s: %s checks nothing" % (where, probe))
        # The probes that mean something: the coordinator ready by its --check, a worker
        # alive by its own.
        wanted = {"cpvs-coordinator": ("readinessProbe", "cpvs-server"), "cpvs-worker": ("livenessProbe", "cpvs-worker")}
        if name in wanted:
            probe, program = wanted[name]
            command = ((c.get(probe) or {}).get("exec") or {}).get("command") or []
            if command[:2] != [program, "--check"]:
                fail("%s: %s is not `%s --check`" % (where, probe, program))
        if "metrics" not in ports:
            fail("%s names no metrics port" % where)
        args = c.get("args") or []
        if "cpvs-worker" in args:
            grace = w["spec"]["template"]["spec"].get("terminationGracePeriodSeconds", 30)
            if "--drain-seconds" not in args:
                fail("%s: no --drain-seconds (a SIGTERM would wait for the tile however long it takes)" % where)
            elif float(args[args.index("--drain-seconds") + 1]) + 5 > grace:
                fail("%s: --drain-seconds leaves under 5 s of the %s s grace period" % (where, grace))
for d in docs:
    if d.get("kind") == "HorizontalPodAutoscaler":
        t = d["spec"].get("scaleTargetRef") or {}
        if (t.get("kind"), t.get("name")) not in workloads:
            fail("HorizontalPodAutoscaler %s targets %s %s, not rendered" % (d["metadata"]["name"], t.get("kind"), t.get("name")))
if failures:
    sys.exit(1)
print("ok:   kubectl kustomize %s renders %d objects (%s); images %s; probes and resources resolve" % (
    kust_path, len(docs), ", ".join("%d %s" % (n, k) for k, n in sorted(counts.items())), ", ".join(sorted(images.values()))))
PY
    then :
    else
      fail "the objects kubectl kustomize ${dir#"$ROOT"/} renders (see above)"
    fi
    rm -f "$rendered"
  done
fi

if [ "$failures" -gt 0 ]; then
  echo "deploy_test: $failures failure(s)" >&2
  exit 1
fi
echo "deploy_test: all checks passed"
