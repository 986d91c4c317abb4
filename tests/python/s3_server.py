"""An S3-compatible server on loopback for the tests: moto's standalone server (PyPI `moto[server]`,
an in-memory S3 that answers SigV4-signed requests, ranges and conditional writes as S3 does).

Prints `ready PORT` once it listens on 127.0.0.1:PORT (a free port), then reads commands on stdin,
one per line, answering each with one line:
  put BUCKET PREFIX FOLDER   every file under FOLDER as PREFIX/relative/path (the bucket made if
                             missing) -> `done N`
  bucket NAME                a bucket -> `done 1`
  write BUCKET KEY TEXT      one object holding TEXT -> `done 1`
  upload BUCKET KEY FILE     one object holding FILE's bytes -> `done 1`
  delete BUCKET KEY          -> `done 1`
  public BUCKET KEY          the object readable by anyone (plain HTTP GET) -> `done 1`
  faults every N CODE        from now on every N-th request of the program under test is
                             answered CODE (503 SlowDown, 500 InternalError, 429 SlowDown) -> `done 1`
  faults down SECONDS        every request of the program under test answered 503 for SECONDS
  faults quota BYTES         uploads beyond BYTES in all refused (403 QuotaExceeded, not retried)
  faults none                -> `done 1`
  stats                      requests of the program under test since the last `stats`, by
                             method, and bytes in and out -> `done GET=n PUT=n … in=B out=B`
  compare BUCKET PREFIX FOLDER  whether the objects under PREFIX/ are exactly FOLDER's files
                             (names beginning with `.` left out), byte for byte -> `done N`, or
                             `error` and what differs
The server stops when stdin closes (the test ends, or dies).
"""

import os
import sys
import threading
import time

import boto3
from botocore.config import Config
from moto.moto_server.werkzeug_app import (
    DomainDispatcherApplication,
    MotoRequestHandler,
    create_backend_app,
)
from werkzeug.serving import make_server

# the requests of this script itself (uploads, comparisons) are never faulted
CONTROL = "sphereclip-test-control"
CODES = {500: "InternalError", 503: "SlowDown", 429: "SlowDown"}


class Faults:
    """Fails requests of the program under test as the test asks (WSGI middleware)."""

    def __init__(self, app):
        self.app = app
        self.lock = threading.Lock()
        self.mode = ("none",)
        self.count = 0
        self.uploaded = 0
        self.stats = {}

    def take_stats(self):
        with self.lock:
            stats, self.stats = self.stats, {}
        return " ".join(f"{k}={v}" for k, v in sorted(stats.items()))

    def note(self, key, n):
        with self.lock:
            self.stats[key] = self.stats.get(key, 0) + n

    def set(self, mode):
        with self.lock:
            self.mode = mode
            self.count = 0
            self.uploaded = 0

    def refuse(self, start, status, code, message):
        body = (
            '<?xml version="1.0" encoding="UTF-8"?>'
            f"<Error><Code>{code}</Code><Message>{message}</Message></Error>"
        ).encode()
        start(
            f"{status} {code}",
            [("Content-Type", "application/xml"), ("Content-Length", str(len(body)))],
        )
        return [body]

    def __call__(self, environ, start):
        if CONTROL in environ.get("HTTP_USER_AGENT", ""):
            return self.app(environ, start)
        self.note(environ["REQUEST_METHOD"], 1)
        self.note("in", int(environ.get("CONTENT_LENGTH") or 0))
        inner = start

        def start(status, headers, *rest):
            for k, v in headers:
                if k.lower() == "content-length":
                    self.note("out", int(v))
            return inner(status, headers, *rest)

        with self.lock:
            mode = self.mode
            self.count += 1
            n = self.count
            size = int(environ.get("CONTENT_LENGTH") or 0)
            if environ["REQUEST_METHOD"] == "PUT":
                self.uploaded += size
            uploaded = self.uploaded
        if mode[0] == "every" and n % mode[1] == 0:
            return self.refuse(start, mode[2], CODES[mode[2]], "injected by the test")
        if mode[0] == "down" and time.monotonic() < mode[1]:
            return self.refuse(start, 503, "ServiceUnavailable", "the server is restarting")
        if mode[0] == "quota" and environ["REQUEST_METHOD"] == "PUT" and uploaded > mode[1]:
            environ["wsgi.input"].read(size)
            return self.refuse(start, 403, "QuotaExceeded", "the bucket's quota is used up")
        return self.app(environ, start)


def main() -> None:
    faults = Faults(DomainDispatcherApplication(create_backend_app))
    server = make_server(
        "127.0.0.1", 0, faults, threaded=True, request_handler=MotoRequestHandler
    )
    threading.Thread(target=server.serve_forever, daemon=True).start()
    port = server.server_address[1]
    s3 = boto3.client(
        "s3",
        endpoint_url=f"http://127.0.0.1:{port}",
        aws_access_key_id="sphereclip-test",
        aws_secret_access_key="sphereclip-test-secret",
        region_name="us-east-1",
        config=Config(user_agent_extra=CONTROL),
    )
    print(f"ready {port}", flush=True)
    for line in sys.stdin:
        words = line.rstrip("\n").split(" ", 3)
        try:
            if words[0] == "put":
                bucket, prefix, folder = words[1:4]
                made = {b["Name"] for b in s3.list_buckets().get("Buckets", [])}
                if bucket not in made:
                    s3.create_bucket(Bucket=bucket)
                n = 0
                for root, _dirs, files in os.walk(folder):
                    for f in sorted(files):
                        path = os.path.join(root, f)
                        key = f"{prefix}/{os.path.relpath(path, folder)}"
                        s3.upload_file(path, bucket, key)
                        n += 1
                print(f"done {n}", flush=True)
            elif words[0] == "faults":
                what = words[1]
                if what == "every":
                    faults.set(("every", int(words[2]), int(words[3])))
                elif what == "down":
                    faults.set(("down", time.monotonic() + float(words[2])))
                elif what == "quota":
                    faults.set(("quota", int(words[2])))
                else:
                    faults.set(("none",))
                print("done 1", flush=True)
            elif words[0] == "stats":
                print(f"done {faults.take_stats()}", flush=True)
            elif words[0] == "bucket":
                s3.create_bucket(Bucket=words[1])
                print("done 1", flush=True)
            elif words[0] == "write":
                bucket, key, body = words[1:4]
                s3.put_object(Bucket=bucket, Key=key, Body=body.encode())
                print("done 1", flush=True)
            elif words[0] == "upload":
                bucket, key, path = words[1:4]
                s3.upload_file(path, bucket, key)
                print("done 1", flush=True)
            elif words[0] == "public":
                bucket, key = words[1:3]
                s3.put_object_acl(Bucket=bucket, Key=key, ACL="public-read")
                print("done 1", flush=True)
            elif words[0] == "compare":
                bucket, prefix, folder = words[1:4]
                local = {}
                for root, dirs, files in os.walk(folder):
                    dirs[:] = [d for d in dirs if not d.startswith(".")]
                    for f in files:
                        if not f.startswith("."):
                            path = os.path.join(root, f)
                            local[os.path.relpath(path, folder)] = path
                remote = []
                pages = s3.get_paginator("list_objects_v2")
                for page in pages.paginate(Bucket=bucket, Prefix=prefix + "/"):
                    remote += [o["Key"][len(prefix) + 1 :] for o in page.get("Contents", [])]
                differ = sorted(set(remote) ^ set(local))
                for key in sorted(set(remote) & set(local)):
                    body = s3.get_object(Bucket=bucket, Key=f"{prefix}/{key}")["Body"].read()
                    with open(local[key], "rb") as f:
                        if f.read() != body:
                            differ.append(key)
                if differ:
                    print(f"error differ: {' '.join(differ[:10])}", flush=True)
                else:
                    print(f"done {len(local)}", flush=True)
            elif words[0] == "delete":
                bucket, key = words[1:3]
                s3.delete_object(Bucket=bucket, Key=key)
                print("done 1", flush=True)
            else:
                print(f"error unknown command {words[0]!r}", flush=True)
        except Exception as e:  # noqa: BLE001 - the test reads the line
            print(f"error {type(e).__name__}: {e}".replace("\n", " "), flush=True)
    server.shutdown()


if __name__ == "__main__":
    main()
