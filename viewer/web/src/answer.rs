//! What an HTTP answer to a store read means: the rules of the page's source, apart from the
//! browser that fetches (so they are tested natively). A server may ignore `Range` and send the
//! whole object (200); a range answer (206) must say where its bytes lie (`Content-Range`).

use std::io;

/// An HTTP answer: its status, its `Content-Range` header and its body.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Answer {
    /// The status code; 0 when no answer came (the browser's network error; the body says why).
    pub status: u16,
    /// The `Content-Range` header, if any.
    pub content_range: Option<String>,
    /// The body.
    pub body: Vec<u8>,
}

impl Answer {
    /// No answer came: `why` (the server is unreachable, or did not answer in time).
    pub fn none(why: String) -> Self {
        Self {
            status: 0,
            content_range: None,
            body: why.into_bytes(),
        }
    }
}

fn bad(url: &str, what: String) -> io::Error {
    io::Error::other(format!("{url}: {what}"))
}

fn failed(url: &str, a: &Answer) -> io::Error {
    if a.status == 0 {
        let why = String::from_utf8_lossy(&a.body);
        let why = if why.is_empty() {
            "the server is unreachable or refused the request"
        } else {
            &why
        };
        io::Error::new(
            io::ErrorKind::ConnectionRefused,
            format!("{url}: no answer ({why})"),
        )
    } else {
        bad(url, format!("HTTP {}", a.status))
    }
}

/// `bytes START-END/TOTAL` → (start, end inclusive, total); `*` as the total is unknown.
pub fn content_range(value: &str) -> Option<(u64, u64, Option<u64>)> {
    let rest = value.trim().strip_prefix("bytes ")?;
    let (span, total) = rest.split_once('/')?;
    let (a, b) = span.split_once('-')?;
    let (a, b) = (a.trim().parse().ok()?, b.trim().parse().ok()?);
    let total = match total.trim() {
        "*" => None,
        t => Some(t.parse().ok()?),
    };
    (a <= b && total.is_none_or(|t| b < t)).then_some((a, b, total))
}

/// The whole object of a GET: `None` for 404, an error above `limit` bytes.
pub fn whole(url: &str, a: Answer, limit: u64) -> io::Result<Option<Vec<u8>>> {
    match a.status {
        404 | 410 => Ok(None),
        200 => {
            if a.body.len() as u64 > limit {
                return Err(bad(
                    url,
                    format!("{} bytes, more than the {limit} allowed", a.body.len()),
                ));
            }
            Ok(Some(a.body))
        }
        _ => Err(failed(url, &a)),
    }
}

/// The last `len` bytes and the object's size, from the answer to `Range: bytes=-len`.
pub fn suffix(url: &str, a: Answer, len: u64) -> io::Result<Option<(u64, Vec<u8>)>> {
    match a.status {
        404 | 410 => Ok(None),
        200 => {
            let size = a.body.len() as u64;
            let from = size.saturating_sub(len) as usize;
            Ok(Some((size, a.body[from..].to_vec())))
        }
        206 => {
            let (start, end, total) = a
                .content_range
                .as_deref()
                .and_then(content_range)
                .ok_or_else(|| bad(url, "a range answer without a valid Content-Range".into()))?;
            let total = total.ok_or_else(|| bad(url, "a range answer of unknown size".into()))?;
            if end + 1 != total
                || end - start + 1 != a.body.len() as u64
                || a.body.len() as u64 > len
            {
                return Err(bad(url, "the range answer is not the object's end".into()));
            }
            Ok(Some((total, a.body)))
        }
        _ => Err(failed(url, &a)),
    }
}

/// `len` bytes from `offset`, from the answer to `Range: bytes=offset-(offset+len−1)`.
pub fn range(url: &str, a: Answer, offset: u64, len: u64) -> io::Result<Vec<u8>> {
    match a.status {
        200 => {
            let end = offset
                .checked_add(len)
                .filter(|&e| e <= a.body.len() as u64);
            let end = end.ok_or_else(|| bad(url, "the object ends before the range".into()))?;
            Ok(a.body[offset as usize..end as usize].to_vec())
        }
        206 => {
            let (start, end, _) = a
                .content_range
                .as_deref()
                .and_then(content_range)
                .ok_or_else(|| bad(url, "a range answer without a valid Content-Range".into()))?;
            if start != offset || end - start + 1 != len || a.body.len() as u64 != len {
                return Err(bad(
                    url,
                    "the range answer is not the range asked for".into(),
                ));
            }
            Ok(a.body)
        }
        404 | 410 => Err(io::Error::new(
            io::ErrorKind::NotFound,
            format!("{url}: no such object"),
        )),
        _ => Err(failed(url, &a)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn answer(status: u16, cr: Option<&str>, body: &[u8]) -> Answer {
        Answer {
            status,
            content_range: cr.map(String::from),
            body: body.to_vec(),
        }
    }

    #[test]
    fn content_ranges_parse_and_nonsense_does_not() {
        assert_eq!(content_range("bytes 0-9/100"), Some((0, 9, Some(100))));
        assert_eq!(content_range("bytes 5-5/*"), Some((5, 5, None)));
        for v in [
            "bytes 9-0/100",
            "bytes 0-100/100",
            "0-9/100",
            "bytes a-9/100",
            "bytes 0-9",
        ] {
            assert_eq!(content_range(v), None, "{v}");
        }
    }

    #[test]
    fn ranges_take_a_server_that_ignores_range_and_refuse_a_wrong_answer() {
        let body: Vec<u8> = (0..100).collect();
        // the server sent the whole object
        assert_eq!(
            range("u", answer(200, None, &body), 10, 5).expect("200"),
            vec![10, 11, 12, 13, 14]
        );
        assert!(range("u", answer(200, None, &body), 98, 5).is_err());
        assert_eq!(
            range(
                "u",
                answer(206, Some("bytes 10-14/100"), &body[10..15]),
                10,
                5
            )
            .expect("206"),
            body[10..15]
        );
        // another range than asked, a short body, no header
        assert!(
            range(
                "u",
                answer(206, Some("bytes 11-15/100"), &body[11..16]),
                10,
                5
            )
            .is_err()
        );
        assert!(
            range(
                "u",
                answer(206, Some("bytes 10-14/100"), &body[10..13]),
                10,
                5
            )
            .is_err()
        );
        assert!(range("u", answer(206, None, &body[10..15]), 10, 5).is_err());
        assert_eq!(
            range("u", answer(404, None, b""), 0, 1)
                .expect_err("404")
                .kind(),
            io::ErrorKind::NotFound
        );
        assert_eq!(
            range("u", answer(0, None, b""), 0, 1)
                .expect_err("no answer")
                .kind(),
            io::ErrorKind::ConnectionRefused
        );
        let late = range("u", Answer::none("none in 20 s".into()), 0, 1).expect_err("late");
        assert_eq!(late.to_string(), "u: no answer (none in 20 s)");
        assert!(range("u", answer(500, None, b""), 0, 1).is_err());
    }

    #[test]
    fn suffixes_and_whole_objects() {
        let body: Vec<u8> = (0..100).collect();
        assert_eq!(
            suffix("u", answer(200, None, &body), 4).expect("200"),
            Some((100, vec![96, 97, 98, 99]))
        );
        assert_eq!(
            suffix("u", answer(206, Some("bytes 96-99/100"), &body[96..]), 4).expect("206"),
            Some((100, vec![96, 97, 98, 99]))
        );
        // not the end of the object
        assert!(suffix("u", answer(206, Some("bytes 90-93/100"), &body[90..94]), 4).is_err());
        assert_eq!(suffix("u", answer(404, None, b""), 4).expect("404"), None);
        assert_eq!(whole("u", answer(404, None, b""), 10).expect("404"), None);
        assert!(whole("u", answer(200, None, &body), 10).is_err());
        assert!(whole("u", answer(503, None, b""), 10).is_err());
    }
}
