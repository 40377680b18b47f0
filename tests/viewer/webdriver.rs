//! A minimal WebDriver client (W3C WebDriver over HTTP/1.1, JSON bodies) for
//! driving headless Chromium through chromedriver: no crate beyond serde_json,
//! one request per connection (`Connection: close`).

use std::io::{Read, Write};
use std::net::{Ipv4Addr, TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::{json, Value};

/// The key WebDriver names a found element by.
const ELEMENT: &str = "element-6066-11e4-a52e-4f735466cecf";
/// WebDriver's code points for the arrow keys.
pub const ARROW_LEFT: &str = "\u{E012}";
pub const ARROW_RIGHT: &str = "\u{E014}";

/// The first of `names` found on `PATH`.
pub fn which(names: &[&str]) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    names.iter().find_map(|n| {
        std::env::split_paths(&path)
            .map(|d| d.join(n))
            .find(|p| p.is_file())
    })
}

/// A chromedriver process and one browser session; both end when dropped.
pub struct Browser {
    driver: Child,
    port: u16,
    session: String,
    _profile: tempfile::TempDir,
}

/// A found element.
#[derive(Clone, Debug)]
pub struct Element(String);

impl Browser {
    /// Starts `driver` and a headless `chromium` session in a fresh profile, with a
    /// `width` x `height` window at one device pixel per CSS pixel and the browser's
    /// console collected.
    pub fn start(chromium: &Path, driver: &Path, width: u32, height: u32) -> Browser {
        let port = {
            let l = TcpListener::bind((Ipv4Addr::LOCALHOST, 0)).expect("a free port");
            l.local_addr().unwrap().port()
        };
        let child = Command::new(driver)
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("chromedriver starts");
        let profile = tempfile::tempdir().unwrap();
        let mut b = Browser {
            driver: child,
            port,
            session: String::new(),
            _profile: profile,
        };
        let deadline = Instant::now() + Duration::from_secs(15);
        loop {
            let last = match b.try_request("GET", "/status", None) {
                Ok(v) if v["value"]["ready"] == true => break,
                Ok(v) => v.to_string(),
                Err(e) => e.to_string(),
            };
            assert!(
                Instant::now() < deadline,
                "chromedriver did not become ready in 15 s: {last}"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
        let args = vec![
            "--headless".to_string(),
            "--no-sandbox".into(),
            "--disable-gpu".into(),
            "--disable-quic".into(),
            "--no-first-run".into(),
            "--disable-background-networking".into(),
            "--disable-component-update".into(),
            "--disable-sync".into(),
            "--disable-dev-shm-usage".into(),
            "--force-device-scale-factor=1".into(),
            format!("--window-size={width},{height}"),
            format!("--user-data-dir={}", b._profile.path().display()),
        ];
        let caps = json!({ "capabilities": { "alwaysMatch": {
            "browserName": "chrome",
            "goog:chromeOptions": { "binary": chromium, "args": args },
            "goog:loggingPrefs": { "browser": "ALL" },
        }}});
        let v = b.request("POST", "/session", Some(caps));
        b.session = v["value"]["sessionId"]
            .as_str()
            .unwrap_or_else(|| panic!("no session: {v}"))
            .to_string();
        b
    }

    fn try_request(&self, method: &str, path: &str, body: Option<Value>) -> std::io::Result<Value> {
        let body = body.map(|b| b.to_string()).unwrap_or_default();
        let mut s = TcpStream::connect((Ipv4Addr::LOCALHOST, self.port))?;
        // before chromedriver listens, a connection to a port of the ephemeral range
        // can connect to itself (TCP simultaneous open), and would wait for its own
        // request to be answered
        if s.local_addr()? == s.peer_addr()? {
            return Err(std::io::Error::other(
                "connected to itself: not listening yet",
            ));
        }
        s.set_read_timeout(Some(Duration::from_secs(60)))?;
        let request = format!(
            "{method} {path} HTTP/1.1\r\nHost: 127.0.0.1:{}\r\nContent-Type: application/json; charset=utf-8\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
            self.port,
            body.len()
        );
        s.write_all(request.as_bytes())?;
        // read the header, then the body by its length (chromedriver may keep the
        // connection open despite `Connection: close`)
        let mut raw = Vec::new();
        let mut buf = [0u8; 1 << 16];
        let mut header: Option<(usize, Option<usize>)> = None;
        loop {
            if let Some((start, Some(len))) = header {
                if raw.len() >= start + len {
                    raw.truncate(start + len);
                    break;
                }
            }
            let n = s.read(&mut buf)?;
            if n == 0 {
                break;
            }
            raw.extend_from_slice(&buf[..n]);
            if header.is_none() {
                if let Some(split) = raw.windows(4).position(|w| w == b"\r\n\r\n") {
                    let head = String::from_utf8_lossy(&raw[..split]).to_ascii_lowercase();
                    let len = head.lines().find_map(|l| {
                        l.strip_prefix("content-length:")
                            .and_then(|v| v.trim().parse().ok())
                    });
                    header = Some((split + 4, len));
                }
            }
        }
        let (start, _) = header.ok_or_else(|| std::io::Error::other("no HTTP header"))?;
        let head = String::from_utf8_lossy(&raw[..start]).to_ascii_lowercase();
        let mut payload = raw[start..].to_vec();
        if head.contains("transfer-encoding: chunked") {
            payload = dechunk(&payload);
        }
        serde_json::from_slice(&payload).map_err(std::io::Error::other)
    }

    /// One WebDriver command; a WebDriver error fails the test with its message.
    fn request(&self, method: &str, path: &str, body: Option<Value>) -> Value {
        let v = self
            .try_request(method, path, body)
            .unwrap_or_else(|e| panic!("WebDriver {method} {path}: {e}"));
        if let Some(err) = v["value"].get("error") {
            panic!(
                "WebDriver {method} {path}: {err}: {}",
                v["value"]["message"]
            );
        }
        v
    }

    fn session_path(&self, rest: &str) -> String {
        format!("/session/{}{rest}", self.session)
    }

    /// Opens `url` and waits for the page to load.
    pub fn goto(&self, url: &str) {
        self.request(
            "POST",
            &self.session_path("/url"),
            Some(json!({ "url": url })),
        );
    }

    /// Runs `script` (a function body; `arguments` are `args`) and returns its value.
    pub fn eval(&self, script: &str, args: Value) -> Value {
        self.request(
            "POST",
            &self.session_path("/execute/sync"),
            Some(json!({ "script": script, "args": args })),
        )["value"]
            .clone()
    }

    /// Waits until `script` returns `true`, failing after `timeout`.
    pub fn wait_for(&self, script: &str, timeout: Duration, what: &str) {
        let deadline = Instant::now() + timeout;
        while self.eval(script, json!([])) != true {
            assert!(Instant::now() < deadline, "timed out waiting for {what}");
            std::thread::sleep(Duration::from_millis(25));
        }
    }

    /// The element matching the CSS `selector`.
    pub fn find(&self, selector: &str) -> Element {
        let v = self.request(
            "POST",
            &self.session_path("/element"),
            Some(json!({ "using": "css selector", "value": selector })),
        );
        Element(
            v["value"][ELEMENT]
                .as_str()
                .expect("an element")
                .to_string(),
        )
    }

    /// An attribute or property of `e` (`null` when absent).
    pub fn attribute(&self, e: &Element, name: &str) -> Value {
        self.request(
            "GET",
            &self.session_path(&format!("/element/{}/attribute/{name}", e.0)),
            None,
        )["value"]
            .clone()
    }

    /// The visible text of `e`.
    pub fn text(&self, e: &Element) -> String {
        self.request(
            "GET",
            &self.session_path(&format!("/element/{}/text", e.0)),
            None,
        )["value"]
            .as_str()
            .unwrap_or_default()
            .to_string()
    }

    /// Clicks `e` (a real click at its centre).
    pub fn click(&self, e: &Element) {
        self.request(
            "POST",
            &self.session_path(&format!("/element/{}/click", e.0)),
            Some(json!({})),
        );
    }

    /// A real mouse drag: press at `(x, y)` from the centre of `e`, move by `dx`
    /// pixels to the right in `steps` moves, release.
    pub fn drag(&self, e: &Element, x: i64, y: i64, dx: i64, steps: i64) {
        self.drag_with("mouse", e, x, y, dx, steps);
    }

    /// [`Browser::drag`] with a `"mouse"`, `"pen"` or `"touch"` pointer.
    pub fn drag_with(&self, pointer: &str, e: &Element, x: i64, y: i64, dx: i64, steps: i64) {
        let origin = json!({ ELEMENT: e.0 });
        let mut actions = vec![
            json!({ "type": "pointerMove", "duration": 0, "origin": origin, "x": x, "y": y }),
            json!({ "type": "pointerDown", "button": 0 }),
        ];
        let mut done = 0;
        for i in 1..=steps {
            let to = dx * i / steps;
            actions.push(json!({ "type": "pointerMove", "duration": 10, "origin": "pointer", "x": to - done, "y": 0 }));
            done = to;
        }
        actions.push(json!({ "type": "pointerUp", "button": 0 }));
        self.actions(json!([{
            "type": "pointer", "id": pointer, "parameters": { "pointerType": pointer },
            "actions": actions,
        }]));
    }

    /// A real key press (down and up) of `key` (a character or a WebDriver key code).
    pub fn press(&self, key: &str) {
        self.actions(json!([{
            "type": "key", "id": "keyboard",
            "actions": [{ "type": "keyDown", "value": key }, { "type": "keyUp", "value": key }],
        }]));
    }

    fn actions(&self, list: Value) {
        self.request(
            "POST",
            &self.session_path("/actions"),
            Some(json!({ "actions": list })),
        );
        self.request("DELETE", &self.session_path("/actions"), None);
    }

    /// A PNG screenshot of `e` (or of the window).
    pub fn screenshot(&self, e: Option<&Element>) -> Vec<u8> {
        let path = match e {
            Some(e) => self.session_path(&format!("/element/{}/screenshot", e.0)),
            None => self.session_path("/screenshot"),
        };
        let v = self.request("GET", &path, None);
        base64(v["value"].as_str().expect("base64 PNG"))
    }

    /// The browser's console and network log entries since the last call, as
    /// (level, message).
    pub fn log(&self) -> Vec<(String, String)> {
        let v = self.request(
            "POST",
            &self.session_path("/se/log"),
            Some(json!({ "type": "browser" })),
        );
        v["value"]
            .as_array()
            .map(|a| {
                a.iter()
                    .map(|e| {
                        (
                            e["level"].as_str().unwrap_or_default().to_string(),
                            e["message"].as_str().unwrap_or_default().to_string(),
                        )
                    })
                    .collect()
            })
            .unwrap_or_default()
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        if !self.session.is_empty() {
            let _ = self.try_request("DELETE", &self.session_path(""), None);
        }
        let _ = self.driver.kill();
        let _ = self.driver.wait();
    }
}

/// The body of a chunked HTTP response.
fn dechunk(mut data: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    while let Some(eol) = data.windows(2).position(|w| w == b"\r\n") {
        let size_text = String::from_utf8_lossy(&data[..eol]);
        let size = usize::from_str_radix(size_text.split(';').next().unwrap_or("0").trim(), 16)
            .unwrap_or(0);
        if size == 0 || data.len() < eol + 2 + size {
            break;
        }
        out.extend_from_slice(&data[eol + 2..eol + 2 + size]);
        data = &data[(eol + 4 + size).min(data.len())..];
    }
    out
}

/// Standard base64 (with padding) decoded.
fn base64(text: &str) -> Vec<u8> {
    let value = |c: u8| -> Option<u32> {
        Some(match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => return None,
        } as u32)
    };
    let mut out = Vec::with_capacity(text.len() * 3 / 4);
    let (mut acc, mut bits) = (0u32, 0);
    for v in text.bytes().filter_map(value) {
        acc = (acc << 6) | v;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
        }
    }
    out
}

#[test]
fn base64_and_chunks_decode() {
    assert_eq!(base64("aGVsbG8gd29ybGQ="), b"hello world");
    assert_eq!(base64("AP8="), [0, 255]);
    assert_eq!(
        dechunk(b"5\r\nhello\r\n6\r\n world\r\n0\r\n\r\n"),
        b"hello world"
    );
}
