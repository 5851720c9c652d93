// MathJax 3 configuration for pymdownx.arithmatex (generic mode): the planner pages' equations, and a heading's
// formula where the navigation shows the heading (its text is in an md-ellipsis span). MathJax itself is
// javascripts/mathjax/tex-chtml.js, added to the site by mkdocs_hooks.py.
window.MathJax = {
  tex: {
    inlineMath: [["\\(", "\\)"]],
    displayMath: [["\\[", "\\]"]],
    processEscapes: true,
    processEnvironments: true
  },
  options: {
    ignoreHtmlClass: ".*|",
    processHtmlClass: "arithmatex|md-ellipsis"
  }
};
