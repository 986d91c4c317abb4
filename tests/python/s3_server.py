"""An S3-compatible server on loopback for the tests: moto's standalone server (PyPI `moto[server]`,
an in-memory S3 that answers SigV4-signed requests, ranges and conditional writes as S3 does).

Prints `ready PORT` once it listens on 127.0.0.1:PORT (a free port), then reads commands on stdin,
one per line, answering each with one line:
  put BUCKET PREFIX FOLDER   every file under FOLDER as PREFIX/relative/path (the bucket made if
                             missing) -> `done N`
  bucket NAME                a bucket -> `done 1`
  write BUCKET KEY TEXT      one object holding TEXT -> `done 1`
  delete BUCKET KEY          -> `done 1`
  public BUCKET KEY          the object readable by anyone (plain HTTP GET) -> `done 1`
  compare BUCKET PREFIX FOLDER  whether the objects under PREFIX/ are exactly FOLDER's files
                             (names beginning with `.` left out), byte for byte -> `done N`, or
                             `error` and what differs
The server stops when stdin closes (the test ends, or dies).
"""

import os
import sys

import boto3
from moto.moto_server.threaded_moto_server import ThreadedMotoServer


def main() -> None:
    server = ThreadedMotoServer(ip_address="127.0.0.1", port=0, verbose=False)
    server.start()
    port = server.get_host_and_port()[1]
    s3 = boto3.client(
        "s3",
        endpoint_url=f"http://127.0.0.1:{port}",
        aws_access_key_id="sphereclip-test",
        aws_secret_access_key="sphereclip-test-secret",
        region_name="us-east-1",
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
            elif words[0] == "bucket":
                s3.create_bucket(Bucket=words[1])
                print("done 1", flush=True)
            elif words[0] == "write":
                bucket, key, body = words[1:4]
                s3.put_object(Bucket=bucket, Key=key, Body=body.encode())
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
    server.stop()


if __name__ == "__main__":
    main()
