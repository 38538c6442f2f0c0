//! A stack drawn as a picture: one model, rendered as DOT, SVG or HTML.
