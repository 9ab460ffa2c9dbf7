//! The `Content-Disposition` of a download (RFC 6266): the file's own name without any
//! path, as a plain ASCII `filename` and, for any other character, `filename*` in UTF-8.
//! Names are the users' (upload names, program names): control characters, quotes and
//! paths never reach the header.

use axum::http::HeaderValue;

pub fn attachment(name: &str) -> HeaderValue {
    // The last path component: `../../etc/passwd` is offered as `passwd`.
    let base = name.rsplit(['/', '\\']).next().unwrap_or("");
    let clean: String = base.chars().filter(|c| !c.is_control()).collect();
    let clean = clean.trim();
    let clean = if clean.is_empty() || clean == "." || clean == ".." {
        "download"
    } else {
        clean
    };
    let ascii: String = clean
        .chars()
        .map(|c| {
            if c.is_ascii_graphic() && c != '"' && c != '\\' || c == ' ' {
                c
            } else {
                '_'
            }
        })
        .collect();
    let mut value = format!("attachment; filename=\"{ascii}\"");
    if ascii != clean {
        let encoded: String = clean
            .bytes()
            .map(|b| {
                if b.is_ascii_alphanumeric() || b"!#$&+-.^_`|~".contains(&b) {
                    (b as char).to_string()
                } else {
                    format!("%{b:02X}")
                }
            })
            .collect();
        value.push_str(&format!("; filename*=UTF-8''{encoded}"));
    }
    HeaderValue::from_str(&value).expect("only visible ASCII is left")
}

#[cfg(test)]
mod tests {
    use super::attachment;

    #[test]
    fn names_are_cleaned_and_non_ascii_ones_carried_in_utf8() {
        let v = |n: &str| attachment(n).to_str().unwrap().to_string();
        assert_eq!(v("part.opt.nc"), "attachment; filename=\"part.opt.nc\"");
        assert_eq!(v("../../etc/passwd"), "attachment; filename=\"passwd\"");
        assert_eq!(v("C:\\cam\\a.nc"), "attachment; filename=\"a.nc\"");
        assert_eq!(
            v("a\r\nSet-Cookie: x.nc"),
            "attachment; filename=\"aSet-Cookie: x.nc\""
        );
        assert_eq!(
            v("q\"uote.nc"),
            "attachment; filename=\"q_uote.nc\"; filename*=UTF-8''q%22uote.nc"
        );
        assert_eq!(
            v("Laufrad ö.nc"),
            "attachment; filename=\"Laufrad _.nc\"; filename*=UTF-8''Laufrad%20%C3%B6.nc"
        );
        assert_eq!(v("\r\n"), "attachment; filename=\"download\"");
    }
}
