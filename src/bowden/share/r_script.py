"""The R script that refits the report's GLMMs from the exported long table (``bowden analyze --export``).

``glmm.R`` is written beside ``outcomes.csv`` / ``outcomes.parquet`` and reads it from its own folder:

    Rscript tables/glmm.R

It refits every model of the report (:func:`bowden.study.statistics.study_statistics`): elevation RMSE
(degrees) and SPARC (sign flipped to positive) over the entire cycle, and the iEMG of each muscle in
each phase, each a gamma GLMM with log link, condition × speed fixed effects (sum-to-zero contrasts)
and a random intercept per participant, on the paper's conditions and speeds only, as the report does:

- ``glmm_pql_reml_*.csv``: the report's fit, SPSS-like pseudo-likelihood (the linearised working
  response refitted by ``nlme::lme`` with REML until the linear predictor changes by < 1e-11, as
  tests/fixtures/stats/make_fixtures.R): coefficients and SEs, ``car::Anova`` type III Wald tests,
  ``emmeans`` marginal means per condition and speed on the response scale with Holm-adjusted pairs;
- ``glmm_laplace_coefficients.csv``: the maximum-likelihood alternative, ``glmmTMB`` (Laplace), and
  ``glmm_lme4_coefficients.csv``, the same by ``lme4::glmer`` (Laplace).

R packages (Debian): r-base-core, r-cran-nlme, r-cran-lme4, r-cran-glmmtmb, r-cran-car, r-cran-emmeans;
r-cran-arrow only for a Parquet export (``--format csv`` needs none). tests/share/test_r_script.py runs
it on a small study and compares it with bowden's fits.
"""

from __future__ import annotations

from pathlib import Path
from typing import Final

from bowden.analysis.outcomes import ELEVATION_RMSE, IEMG_PREFIX, SPARC
from bowden.contracts import CONDITIONS, MUSCLES, SPEEDS

R_SCRIPT_NAME: Final = "glmm.R"


def r_script_path(directory: str | Path) -> Path:
    """Where :func:`write_r_script` writes (to check it beforehand)."""
    return Path(directory) / R_SCRIPT_NAME


def _r_vector(values: tuple[str, ...] | list[str]) -> str:
    return "c(" + ", ".join(f'"{value}"' for value in values) + ")"


def r_script(file_format: str) -> str:
    """The script's text for an export in ``file_format`` (``"csv"`` or ``"parquet"``)."""
    iemg = [IEMG_PREFIX + muscle for muscle in MUSCLES]
    return _TEMPLATE.format(
        file=f"outcomes.{file_format}",
        parquet="TRUE" if file_format == "parquet" else "FALSE",
        conditions=_r_vector(CONDITIONS),
        speeds=_r_vector(SPEEDS),
        rmse=ELEVATION_RMSE,
        sparc=SPARC,
        iemg=_r_vector(iemg),
    )


def write_r_script(directory: str | Path, *, file_format: str) -> Path:
    """Write ``glmm.R`` into ``directory`` (beside the exported ``outcomes`` table); return its path."""
    path = r_script_path(directory)
    path.write_text(r_script(file_format))
    return path


_TEMPLATE: Final = r"""# The report's GLMMs, refitted in R from the long table bowden analyze --export wrote
# beside this file.
#
#   Rscript glmm.R            (writes glmm_*.csv beside this file)
#
# Gamma GLMM, log link, condition * speed (sum-to-zero contrasts), random intercept per participant,
# on the paper's conditions and speeds; elevation RMSE in degrees, SPARC sign-flipped, entire cycle;
# iEMG per muscle and phase. The report's fit is the SPSS-like pseudo-likelihood with REML (PQL-REML).

suppressPackageStartupMessages({{
  library(nlme)
  library(car)
  library(emmeans)
}})
options(contrasts = c("contr.sum", "contr.poly"))
emm_options(msg.interaction = FALSE, msg.nesting = FALSE)

args <- commandArgs(trailingOnly = FALSE)
script <- sub("^--file=", "", args[grep("^--file=", args)])
here <- if (length(script)) dirname(normalizePath(script)) else "."
conditions <- {conditions}
speeds <- {speeds}

table_file <- file.path(here, "{file}")
outcomes <- if ({parquet}) as.data.frame(arrow::read_parquet(table_file)) else
  read.csv(table_file, stringsAsFactors = FALSE)

models <- data.frame(measure = c("{rmse}", "{sparc}"), phase = "entire", stringsAsFactors = FALSE)
for (phase in c("raising", "lowering", "entire")) {{
  models <- rbind(models, data.frame(measure = {iemg}, phase = phase, stringsAsFactors = FALSE))
}}

outcome_data <- function(measure, phase) {{
  d <- outcomes[outcomes$measure == measure & outcomes$phase == phase &
                outcomes$condition %in% conditions & outcomes$speed %in% speeds & !is.na(outcomes$value),
                c("participant", "condition", "speed", "value")]
  if (measure == "{rmse}") d$value <- d$value * 180 / pi
  if (measure == "{sparc}") d$value <- -d$value
  d$condition <- factor(d$condition, levels = conditions[conditions %in% d$condition])
  d$speed <- factor(d$speed, levels = speeds[speeds %in% d$speed])
  d$participant <- factor(d$participant)
  d
}}

lme_control <- lmeControl(maxIter = 1000, msMaxIter = 1000, msMaxEval = 10000, niterEM = 100,
                          tolerance = 1e-13, msTol = 1e-15, returnObject = FALSE)

# SPSS-like PQL: working response z = eta + (y - mu) / mu (unit working weights for gamma/log), lme by
# REML at every step, until the linear predictor stops changing.
pql_reml <- function(d) {{
  start <- glm(value ~ condition * speed, family = Gamma(link = "log"), data = d,
               control = glm.control(epsilon = 1e-12, maxit = 100))
  eta <- predict(start, type = "link")
  for (iter in 1:200) {{
    mu <- exp(eta)
    d$zz <- eta + (d$value - mu) / mu
    fit <- lme(zz ~ condition * speed, random = ~ 1 | participant, data = d, method = "REML",
               control = lme_control)
    eta_new <- as.numeric(fitted(fit, level = 1))
    change <- max(abs(eta_new - eta))
    eta <- eta_new
    if (change < 1e-11) break
  }}
  list(fit = fit, data = d)
}}

labelled <- function(df, measure, phase) {{
  for (k in names(df)) if (is.factor(df[[k]])) df[[k]] <- as.character(df[[k]])
  cbind(data.frame(measure = measure, phase = phase, stringsAsFactors = FALSE), df)
}}

coefficients <- list(); type3 <- list(); emm <- list(); pairs_out <- list(); laplace <- list()
lme4_out <- list(); skipped <- c()
for (k in seq_len(nrow(models))) {{
  measure <- models$measure[k]; phase <- models$phase[k]
  d <- outcome_data(measure, phase)
  if (nrow(d) == 0 || nlevels(d$condition) < 2 || nlevels(d$speed) < 2 || nlevels(d$participant) < 2) {{
    skipped <- c(skipped, paste(measure, phase)); next
  }}
  res <- tryCatch(pql_reml(d), error = function(e) NULL)
  if (is.null(res)) {{ skipped <- c(skipped, paste(measure, phase)); next }}
  fit <- res$fit
  coefficients[[k]] <- labelled(data.frame(term = names(fixef(fit)), estimate = as.numeric(fixef(fit)),
                                           se = as.numeric(sqrt(diag(vcov(fit))))), measure, phase)
  a <- car::Anova(fit, type = 3)
  type3[[k]] <- labelled(data.frame(term = rownames(a), chisq = as.numeric(a$Chisq), df = as.numeric(a$Df),
                                    p = as.numeric(a[["Pr(>Chisq)"]])), measure, phase)
  n_obs <- nrow(res$data); p <- length(fixef(fit))
  rg <- update(ref_grid(fit, data = res$data, sigmaAdjust = FALSE), tran = "log", df = n_obs - p)
  for (factor_name in c("condition", "speed")) {{
    resp <- regrid(emmeans(rg, as.formula(paste("~", factor_name))))
    s <- as.data.frame(summary(resp, infer = c(FALSE, FALSE)))
    names(s)[1] <- "level"
    mean <- if ("response" %in% names(s)) s$response else s$emmean
    emm[[length(emm) + 1]] <- labelled(data.frame(factor = factor_name, level = s$level, mean = mean,
                                                  se = s$SE), measure, phase)
    pr <- as.data.frame(summary(pairs(resp), adjust = "holm", infer = c(FALSE, TRUE)))
    pairs_out[[length(pairs_out) + 1]] <- labelled(data.frame(
      factor = factor_name, contrast = pr$contrast, estimate = pr$estimate, se = pr$SE,
      p_holm = pr$p.value), measure, phase)
  }}
  if (requireNamespace("glmmTMB", quietly = TRUE)) {{
    tmb <- tryCatch(glmmTMB::glmmTMB(value ~ condition * speed + (1 | participant),
                                     family = Gamma(link = "log"), data = d), error = function(e) NULL)
    if (!is.null(tmb)) laplace[[k]] <- labelled(data.frame(
      term = names(glmmTMB::fixef(tmb)$cond), estimate = as.numeric(glmmTMB::fixef(tmb)$cond),
      se = as.numeric(sqrt(diag(vcov(tmb)$cond)))), measure, phase)
  }}
  if (requireNamespace("lme4", quietly = TRUE)) {{
    g <- tryCatch(lme4::glmer(value ~ condition * speed + (1 | participant), family = Gamma(link = "log"),
                              data = d), error = function(e) NULL)
    if (!is.null(g)) lme4_out[[k]] <- labelled(data.frame(
      term = names(lme4::fixef(g)), estimate = as.numeric(lme4::fixef(g)),
      se = as.numeric(sqrt(diag(as.matrix(vcov(g)))))), measure, phase)
  }}
}}

write_all <- function(parts, name) {{
  parts <- Filter(Negate(is.null), parts)
  if (length(parts)) write.csv(do.call(rbind, parts), file.path(here, name), row.names = FALSE)
}}
write_all(coefficients, "glmm_pql_reml_coefficients.csv")
write_all(type3, "glmm_pql_reml_type3.csv")
write_all(emm, "glmm_pql_reml_emmeans.csv")
write_all(pairs_out, "glmm_pql_reml_pairs.csv")
write_all(laplace, "glmm_laplace_coefficients.csv")
write_all(lme4_out, "glmm_lme4_coefficients.csv")
cat(sprintf("refitted %d models; skipped %d%s\n", length(Filter(Negate(is.null), coefficients)),
            length(skipped), if (length(skipped)) paste0(" (", paste(skipped, collapse = "; "), ")") else ""))
"""
