//! `STRING_TO_<type>`: texts whose value the generator knows (a literal it wrote, or what
//! `<integer>_TO_STRING` printed), and any string at all where every value of the type is
//! welcome (rule 13).

use super::*;

impl ProgramGen<'_> {
    /// `STRING_TO_<ty>` of an integer type, with its value in `want`.
    pub(super) fn string_to_int(&mut self, ty: Ty, want: Iv, d: u32) -> Expr {
        let name = format!("STRING_TO_{}", ty.name());
        let exact = want.meet(ty.full());
        match self.rng.below(4) {
            0 => {
                let any = self.string(STR_CAP, d.saturating_sub(1));
                let e = self.call(&name, &[any], Val::Int(ty.full()));
                self.limit_int(e, ty, want)
            }
            1 => {
                let src = *self.rng.pick(INT_TYPES);
                let b = exact.meet(src.full());
                if b.lo > b.hi {
                    let v = self.pick_int(ty, exact);
                    return self.int_lit(ty, v, true);
                }
                let x = self.int(src, b, true, d.saturating_sub(1));
                let iv = x.val.iv();
                let text = self.call(
                    &format!("{}_TO_STRING", src.name()),
                    &[x],
                    Val::Str {
                        min: 1,
                        max: decimal_digits(src),
                    },
                );
                self.call(&name, &[text], Val::Int(iv))
            }
            _ => {
                let v = self.pick_int(ty, exact);
                let text = self.integer_text(v);
                let lit = str_text(&text);
                self.call(&name, &[lit], Val::Int(Iv::point(v)))
            }
        }
    }

    /// `STRING_TO_<ty>` of a bit string: of any string, or of a literal in MATIEC's forms.
    pub(super) fn string_to_bits(&mut self, ty: Ty, d: u32) -> Expr {
        let arg = if self.rng.pct(50) {
            self.string(STR_CAP, d.saturating_sub(1))
        } else {
            let v = self.rng.int(0, ty.full().hi);
            str_text(&self.integer_text(v))
        };
        let name = format!("STRING_TO_{}", ty.name());
        self.call(&name, &[arg], Val::Bits { dirty: false })
    }

    /// `STRING_TO_<ty>` of a REAL or LREAL in `want`: a literal only, since MATIEC's `atof` reads
    /// past the string's length into bytes a variable held before.
    pub(super) fn string_to_real(&mut self, ty: Ty, want: Rv) -> Expr {
        let (v, text) = self.real_value(ty, want);
        let lit = str_text(&text.replace('_', ""));
        let name = format!("STRING_TO_{}", ty.name());
        self.call(&name, &[lit], Val::Real(Rv::padded(v, v)))
    }

    /// `STRING_TO_BOOL` of any string, or of one of the texts that read TRUE.
    pub(super) fn string_to_bool(&mut self, d: u32) -> Expr {
        let arg = if self.rng.pct(40) {
            let texts = ["1", "TRUE", "true", "True", "0", "FALSE", "tru"];
            let text: &&str = self.rng.pick(&texts);
            str_text(text)
        } else {
            self.string(STR_CAP, d.saturating_sub(1))
        };
        self.call("STRING_TO_BOOL", &[arg], Val::Bool)
    }

    /// How MATIEC's `__pstring_to_sint` reads back `v`: its decimal digits (after spaces or a
    /// `+` it skips), or a `2#`, `8#` or `16#` literal when `v` is not negative.
    fn integer_text(&mut self, v: i128) -> String {
        match self.rng.below(6) {
            0 if v >= 0 => based(self.rng, v),
            1 if v >= 0 => format!("+{v}"),
            2 if v >= 0 => format!("  {v}"),
            _ => v.to_string(),
        }
    }
}

/// A STRING literal of `text`, which holds no `'` or `$`.
fn str_text(text: &str) -> Expr {
    let n = text.len() as u32;
    Expr::lit(format!("'{text}'"), Val::Str { min: n, max: n }, true)
}
