"""Validates a Kubernetes manifest against the API's JSON schemas and describes its Indexed Job.

Used by tests/k8s.rs. Each document of the file is validated strictly (unknown fields refused)
with kubernetes-validate against every Kubernetes version given with --versions; then the one
Job and the PersistentVolumeClaims are printed as JSON (what a pod runs, where, with which
volumes), for the test to check and to run the pods' command as the Job would.

Usage: k8s_job.py MANIFEST --versions 1.25 1.37
Exit status: 0 valid (JSON on stdout), 1 invalid (the validator's message on stderr).
"""

import argparse
import json
import sys

import kubernetes_validate
import yaml


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("manifest")
    parser.add_argument("--versions", nargs="+", required=True)
    options = parser.parse_args()
    with open(options.manifest, encoding="utf-8") as f:
        documents = [d for d in yaml.safe_load_all(f) if d is not None]
    failures = []
    for version in options.versions:
        for document in documents:
            name = f"{document.get('kind')}/{document.get('metadata', {}).get('name')}"
            try:
                kubernetes_validate.validate(document, version, strict=True)
            except kubernetes_validate.ValidationError as error:
                failures.append(f"{name} against Kubernetes {version}: {error.message} "
                                f"(at {'.'.join(str(p) for p in error.path)})")
            except Exception as error:  # the validator's own errors (e.g. unknown version)
                failures.append(f"{name} against Kubernetes {version}: {error!r}")
    if failures:
        print("\n".join(failures), file=sys.stderr)
        sys.exit(1)

    jobs = [d for d in documents if d.get("kind") == "Job"]
    claims = [d for d in documents if d.get("kind") == "PersistentVolumeClaim"]
    if len(jobs) != 1:
        print(f"expected one Job in {options.manifest}, found {len(jobs)}", file=sys.stderr)
        sys.exit(1)
    job = jobs[0]
    spec = job["spec"]
    pod = spec["template"]["spec"]
    containers = pod["containers"]
    if len(containers) != 1:
        print(f"expected one container, found {len(containers)}", file=sys.stderr)
        sys.exit(1)
    container = containers[0]
    volumes = {v["name"]: v for v in pod.get("volumes", [])}
    mounts = []
    for mount in container.get("volumeMounts", []):
        volume = volumes.get(mount["name"], {})
        mounts.append({
            "name": mount["name"],
            "mount_path": mount["mountPath"],
            "claim": volume.get("persistentVolumeClaim", {}).get("claimName"),
        })
    description = {
        "job": job["metadata"]["name"],
        "completion_mode": spec.get("completionMode", "NonIndexed"),
        "completions": spec.get("completions"),
        "parallelism": spec.get("parallelism", 1),
        "backoff_limit": spec.get("backoffLimit", 6),
        "restart_policy": pod.get("restartPolicy", "Always"),
        "command": container.get("command", []),
        "args": container.get("args", []),
        "working_dir": container.get("workingDir"),
        "env": [{"name": e["name"], "value": e.get("value", "")} for e in container.get("env", [])],
        "mounts": mounts,
        "claims": [{"name": c["metadata"]["name"],
                    "access_modes": c["spec"].get("accessModes", [])} for c in claims],
    }
    json.dump(description, sys.stdout, indent=1)


if __name__ == "__main__":
    main()
